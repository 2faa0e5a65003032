"""Every registered plug-in under test: the cases are parametrised from jaxfem's registries
(materials.LAWS, elements.ELEMENTS, kinematics.KINDS, linsolve.SOLVERS), so registering a law, an
element, a kind or a solver brings it under test here without editing this file.

- every law: zero energy and stress in the reference state, and the small-strain tangent of
  linear elasticity with the same (E, nu);
- every law x element x kind (2D elements plane stress and plane strain, 3D elements solid) x
  installed solver: the patch test, a homogeneous deformation prescribed on the boundary of a
  tiny mesh and Newton (one run per solver) finding it inside. By default the cases run pairwise
  (every law on one element, every element and kind with one law, every solver in each case); the
  rest of the full product is marked slow;
- every installed solver: a small SPD system from a real tangent solved to 1e-10.

The refine tables derived from the registries (a diagnosis's alternative laws, the bundle's law and
kind names) are pinned as well.
"""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxfem as jf
from jaxfem import linsolve
from jaxfem.elements import ELEMENTS
from jaxfem.kinematics import KINDS, dimension
from jaxfem.materials import LAWS, alternatives

E, NU = 7.0, 0.3
FIRST_LAW, FIRST_ELEMENT = next(iter(LAWS)), next(e for e in ELEMENTS.values() if e.dim == 2).name
INSTALLED = linsolve.available()
ELEMENT_KINDS = [(el.name, kind) for el in ELEMENTS.values() for kind in KINDS if dimension(kind) == el.dim]


# ---------------------------------------------------------------- laws at a point
def _linear_elasticity(E, nu):
    """C[i, j, k, l] = lam d_ij d_kl + mu (d_ik d_jl + d_il d_jk)."""
    mu, lam = jf.lame(E, nu)
    d = np.eye(3)
    return (lam * np.einsum("ij,kl->ijkl", d, d)
            + mu * (np.einsum("ik,jl->ijkl", d, d) + np.einsum("il,jk->ijkl", d, d)))


@pytest.mark.parametrize("law", list(LAWS))
def test_law_is_stress_free_at_identity_with_the_linear_elastic_tangent(law):
    m = LAWS[law]
    p = {"E": jnp.float64(E), "nu": jnp.float64(NU), **{q.name: jnp.float64(q.default) for q in m.extra}}
    eye = jnp.eye(3)
    assert abs(float(m.energy(eye, p))) <= 1e-14 * E
    assert np.abs(np.asarray(jax.grad(m.energy)(eye, p))).max() <= 1e-14 * E
    A = np.asarray(jax.hessian(m.energy)(eye, p))
    # sym(A) on symmetric strains: at a stress-free state A_iJkL = C_iJkL for a finite-strain law
    # (an anisotropic law's C is its own, declared as Material.stiffness)
    C = _linear_elasticity(E, NU) if m.stiffness is None else np.asarray(m.stiffness(p))
    np.testing.assert_allclose(A, C, rtol=0, atol=1e-12 * E)


@pytest.mark.parametrize("law", list(LAWS))
def test_law_extras_start_inside_their_bounds(law):
    for q in LAWS[law].extra:
        assert q.lower <= q.default <= q.upper, q


def test_alternative_laws_are_the_diagnosis_table():
    # the order matters: a diagnosis tries them in this order
    assert {law: alternatives(law) for law in LAWS} == {
        "neo-hookean": ("mooney-rivlin", "saint-venant-kirchhoff", "fibre-reinforced"),
        "mooney-rivlin": ("neo-hookean", "saint-venant-kirchhoff", "fibre-reinforced"),
        "saint-venant-kirchhoff": ("neo-hookean", "mooney-rivlin", "fibre-reinforced"),
        "linear-elastic": ("neo-hookean",),
        "fibre-reinforced": ("neo-hookean", "mooney-rivlin", "saint-venant-kirchhoff")}


def test_every_alternative_is_registered_and_finite():
    for law in LAWS:
        assert all(LAWS[a].finite and a != law for a in alternatives(law))


def test_an_unknown_law_or_solver_says_what_to_use():
    with pytest.raises(ValueError, match="use one of"):
        jf.get_material("hookean")
    pat = jf.assembly.make_pattern(jf.rectangle(0, 0, 1, 1, 1, 1))
    with pytest.raises(jf.JaxfemError, match="use one of"):
        linsolve.make_linear_solver("mumps", pat, 2)


def test_bundle_validates_against_the_registries():
    from refine.bundle.experiment import _registries

    assert _registries() == (KINDS, tuple(LAWS))


# ---------------------------------------------------------------- the patch test
def _mesh(element):
    if ELEMENTS[element].dim == 2:
        return jf.rectangle(0.0, 0.0, 2.0, 2.0, 2, 2, element=element)
    return jf.box(0.0, 0.0, 0.0, 2.0, 2.0, 2.0, 2, 2, 2, element=element)


def _stretch(dim):
    """A homogeneous deformation gradient with stretch and shear (10 % and less)."""
    F = np.eye(dim) + np.array([[0.10, 0.04, 0.02], [0.01, -0.05, 0.03], [0.02, 0.01, 0.06]])[:dim, :dim]
    return F


@functools.lru_cache(maxsize=None)
def _patch(law, element, kind):
    """(solver, theta, affine u, jitted (u -> residual, constrained tangent values)) of the patch."""
    mesh = _mesh(element)
    problem = jf.Problem(mesh, law, kind, fixed=jf.dofs(mesh, mesh.boundary_nodes()))
    F = _stretch(mesh.dim)
    u_affine = mesh.nodes @ (F - np.eye(mesh.dim)).T
    solver = jf.Solver(problem, linear_solver="dense")  # compiles nothing until its Newton runs
    theta = problem.params(E=E, nu=NU, u_D=problem.prescribe(u_affine))
    step = jax.jit(lambda u: (solver.residual(u, theta), solver._constrained(solver.tangent_values(u, theta))))
    return solver, theta, u_affine.reshape(-1), step


@functools.lru_cache(maxsize=None)
def _linear_solver(element, name):
    """The solver ``name`` on the patch mesh of ``element``, jitted once (the pattern is the mesh's)."""
    solver = _patch(FIRST_LAW, element, next(k for k in KINDS if dimension(k) == ELEMENTS[element].dim))[0]
    _, lin = linsolve.make_linear_solver(name, solver.pattern)
    return jax.jit(lambda vals, rhs, arrays: lin(vals, rhs, arrays))


def _newton(law, element, kind, name, iterations=12):
    solver, theta, u_affine, step = _patch(law, element, kind)
    lin, arrays = _linear_solver(element, name), solver.arrays
    free = np.asarray(arrays["free"])
    u = np.where(free > 0, 0.0, u_affine)
    for _ in range(iterations):
        R, vals = step(jnp.asarray(u))
        rhs = -np.asarray(R) * free
        if np.linalg.norm(rhs) <= 1e-12 * E:
            break
        u = u + np.asarray(lin(vals, jnp.asarray(rhs), arrays))
    return u, u_affine, np.linalg.norm(rhs)


def _patch_cases():
    cases = []
    for law in LAWS:
        for element, kind in ELEMENT_KINDS:
            pairwise = law == FIRST_LAW or (element == FIRST_ELEMENT and kind == KINDS[0])
            cases.append(pytest.param(law, element, kind, id=f"{law}-{element}-{kind}",
                                      marks=() if pairwise else pytest.mark.slow))
    return cases


@pytest.mark.parametrize("law, element, kind", _patch_cases())
def test_patch_newton_finds_the_homogeneous_deformation_with_every_solver(law, element, kind):
    for name in INSTALLED:
        u, u_affine, residual = _newton(law, element, kind, name)
        assert residual <= 1e-12 * E, (name, residual)
        assert np.abs(u - u_affine).max() <= 1e-10, (name, np.abs(u - u_affine).max())


# ---------------------------------------------------------------- every solver on an SPD system
@pytest.mark.parametrize("name", INSTALLED)
def test_solver_solves_an_spd_tangent(name):
    element, kind = FIRST_ELEMENT, KINDS[0]
    solver, theta, u_affine, step = _patch(FIRST_LAW, element, kind)
    _, vals = step(jnp.zeros_like(jnp.asarray(u_affine)))  # the reference state: SPD once constrained
    pat = solver.pattern
    A = np.zeros((pat.n_dofs, pat.n_dofs))
    np.add.at(A, (pat.rows, pat.cols), np.asarray(vals))
    assert np.allclose(A, A.T) and np.linalg.eigvalsh(A).min() > 0
    b = np.random.default_rng(0).standard_normal(pat.n_dofs)
    x = np.asarray(_linear_solver(element, name)(vals, jnp.asarray(b), solver.arrays))
    ref = np.linalg.solve(A, b)
    assert np.linalg.norm(x - ref) <= 1e-10 * np.linalg.norm(ref)
