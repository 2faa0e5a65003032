"""Derivatives of the equilibrium u*(theta): Taylor tests for every kind of parameter, forward
against reverse mode, central finite differences of the full nonlinear solve, Hessian-vector
products, batched solves, and geometry through the mesh morph.

Three small problems: a plane-stress plate (tri3) with an elliptic hole and a stiff elliptic
inclusion pulled 20 %, a plane-strain rectangle (quad4) and a 3D box (tet4; hex8 in the slow
set). Each carries a dead traction on its top side and random point forces. The scalar is the
misfit 0.5 |u - m|^2 to a random target m.

Compilation dominates the runtime, so each problem compiles its solver into two programs that
every test shares: ``value_and_grad`` of the misfit (reverse mode, one adjoint solve) and
``jax.jvp`` of theta -> u (forward mode, one tangent solve). :func:`scalar` hands them to
:func:`jaxfem.taylor_test` as an ordinary differentiable function.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass
from functools import cache
from typing import Callable

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxfem as jf
from jaxfem.batch import batch_displacement
from jaxfem.geometry import check_geometry, with_geometry

HOLE, INCLUSION = jf.Ellipse(12, 15, 5, 4, 0.3), jf.Ellipse(28, 15, 5, 6, -0.2)
H0, STEPS, MIN_RATE = 1e-2, 5, 1.8  # remainders from ~1e-4 down to ~1e-8 of f: far above round-off


@dataclass(frozen=True, eq=False)
class Case:
    """A small problem, its parameters, the misfit target and its two compiled programs."""

    name: str
    solver: jf.Solver
    theta: dict
    target: jax.Array  # m, (n_nodes, dim)
    scales: dict  # typical size of a change of each parameter (its units)
    value_and_grad: Callable  # theta -> (misfit, d misfit / d theta)
    jvp: Callable  # (theta, v) -> (u, J v)
    morph: jf.shapes.Morph | None = None

    def value_and_jvp(self, theta, v):
        """Misfit and its derivative along ``v`` (forward mode)."""
        u, du = self.jvp(theta, v)
        r = u - self.target
        return 0.5 * jnp.sum(r * r), jnp.vdot(r, du)


def _problem(name):
    if name == "plane-stress":
        mesh = jf.plate(0, 0, 40, 30, 4.0, holes=[HOLE], inclusions=[INCLUSION])
        stretch, E, xscale = 0.2, np.where(mesh.regions == 1, 40.0, 10.0), 0.5
    elif name == "plane-strain":
        mesh, stretch, E, xscale = jf.rectangle(0, 0, 10, 6, 5, 3, "quad4"), 0.1, 10.0, 0.2
    else:
        mesh, stretch, E, xscale = jf.box(0, 0, 0, 3, 2, 2, 3, 2, 2, name), 0.1, 10.0, 0.1
    fixed = np.concatenate([jf.dofs(mesh, mesh.side("left")), jf.dofs(mesh, mesh.side("right"))])
    kinematics = None if mesh.dim == 3 else name
    problem = jf.Problem(mesh, "neo-hookean", kinematics, fixed=fixed, traction_facets=mesh.side_facets("top"))
    rng = np.random.default_rng(1)
    theta = problem.params(E=E, nu=0.3, u_D=problem.prescribe(lambda X: stretch * X * np.eye(mesh.dim)[0]),
                           f=0.05 * rng.normal(size=problem.n_dofs), traction=0.3 * np.eye(mesh.dim)[1])
    scales = {"E": 2.0, "nu": 0.05, "u_D": 0.5, "f": 0.5, "traction": 0.3, "X": xscale}
    if mesh.dim == 2:
        scales["thickness"] = 0.2
    return mesh, problem, theta, scales


@cache
def case(name: str) -> Case:
    mesh, problem, theta, scales = _problem(name)
    solver = jf.Solver(problem)
    jvp = jax.jit(lambda th, v: jax.jvp(solver.displacement, (th,), (v,)))
    u0, _ = jvp(theta, zeros(theta))
    target = u0 + 0.5 * np.random.default_rng(2).normal(size=u0.shape)  # w = u - m is random

    def misfit(th):
        return 0.5 * jnp.sum((solver.displacement(th) - target) ** 2)

    morph = jf.morph(mesh, [HOLE, INCLUSION]) if name == "plane-stress" else None
    return Case(name, solver, theta, target, scales, jax.jit(jax.value_and_grad(misfit)), jvp, morph)


def zeros(theta):
    return jax.tree.map(jnp.zeros_like, theta)


def rng_for(*labels) -> np.random.Generator:
    """A generator seeded by the test's labels: every direction is reproducible, none is special."""
    return np.random.default_rng(zlib.crc32("/".join(map(str, labels)).encode()))


def direction(c: Case, keys, rng) -> dict:
    """Random normal tangent of the given keys (scaled to their typical change), zero elsewhere."""
    d = zeros(c.theta)
    for k in keys:
        d[k] = jnp.asarray(c.scales[k] * rng.normal(size=c.theta[k].shape))
    return d


def scalar(value_and_grad, value_and_jvp, mode: str):
    """A scalar function of one pytree for :func:`jaxfem.taylor_test`, whose value, gradient (mode
    ``"reverse"``) or JVP (``"forward"``) each run one already compiled program."""
    if mode == "reverse":
        f = jax.custom_vjp(lambda x: value_and_grad(x)[0])
        f.defvjp(value_and_grad, lambda g, ct: (jax.tree.map(lambda a: ct * a, g),))
    else:
        f = jax.custom_jvp(lambda x: value_and_grad(x)[0])
        f.defjvp(lambda primals, tangents: value_and_jvp(primals[0], tangents[0]))
    return f


def geometry_functions(c: Case):
    """Misfit of the shape parameters (2, 5) through ``with_geometry``, chained through the
    compiled programs of the plate: its value and gradient, its value and JVP."""

    def theta_of(p):
        return with_geometry(c.theta, c.morph, p)

    def value_and_grad(p):
        value, g = c.value_and_grad(theta_of(p))
        return value, jax.vjp(theta_of, p)[1](g)[0]

    def value_and_jvp(p, dp):
        th, dth = jax.jvp(theta_of, (p,), (dp,))
        return c.value_and_jvp(th, dth)

    return value_and_grad, value_and_jvp


def vdot(a, b) -> float:
    return float(sum(jnp.vdot(x, y) for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b))))


# ====================================================================== Taylor tests
FIELDS_2D = ["E", "thickness", "nu", "u_D", "f", "traction", "X"]
FIELDS_3D = ["E", "nu", "u_D", "f", "traction", "X"]
TAYLOR = ([("plane-stress", k) for k in FIELDS_2D] + [("plane-strain", k) for k in FIELDS_2D]
          + [("tet4", k) for k in FIELDS_3D]
          + [pytest.param("hex8", k, marks=pytest.mark.slow) for k in FIELDS_3D])


@pytest.mark.parametrize("mode", ["reverse", "forward"])
@pytest.mark.parametrize("name, key", TAYLOR)
def test_taylor_rate_is_two(name, key, mode):
    c = case(name)
    d = direction(c, [key], rng_for(name, key))
    f = scalar(c.value_and_grad, c.value_and_jvp, mode)
    result = jf.taylor_test(f, c.theta, d, h0=H0, steps=STEPS, mode=mode)
    assert result.min_rate > MIN_RATE, f"{name} {key} {mode}\n{result}"


# (cx, cy, a, b, angle) of the hole (row 0) and the inclusion (row 1)
SHAPES = {"hole centre": ([0], [0, 1]), "hole axes": ([0], [2, 3]), "hole angle": ([0], [4]),
          "inclusion centre": ([1], [0, 1]), "inclusion axes": ([1], [2, 3])}


@pytest.mark.parametrize("mode", ["reverse", "forward"])
@pytest.mark.parametrize("what", SHAPES)
def test_taylor_rate_through_the_morph(what, mode):
    c = case("plane-stress")
    rows, cols = SHAPES[what]
    d = np.zeros((2, 5))
    d[np.ix_(rows, cols)] = rng_for("shape", what).normal(size=(len(rows), len(cols)))
    d[:, 4] *= 0.05  # radians
    f = scalar(*geometry_functions(c), mode)
    result = jf.taylor_test(f, jnp.asarray(c.morph.params0), jnp.asarray(d), h0=H0, steps=STEPS, mode=mode)
    assert result.min_rate > MIN_RATE, f"{what} {mode}\n{result}"


# ====================================================================== consistency
CASES = ["plane-stress", "plane-strain", "tet4"]


@pytest.mark.parametrize("name", CASES)
def test_forward_and_reverse_mode_agree(name):
    """w . (J v) from jax.jvp equals (J^T w) . v from reverse mode, for random v and w = u - m."""
    c = case(name)
    v = direction(c, c.scales, rng_for(name, "adjoint"))
    u, Jv = c.jvp(c.theta, v)
    _, JTw = c.value_and_grad(c.theta)  # J^T (u - m)
    lhs, rhs = float(jnp.vdot(u - c.target, Jv)), vdot(JTw, v)
    assert lhs == pytest.approx(rhs, rel=1e-10), (lhs, rhs)


@pytest.mark.parametrize("name", CASES)
def test_gradient_matches_central_differences(name):
    c = case(name)
    _, g = c.value_and_grad(c.theta)
    rng = rng_for(name, "fd")
    value = lambda th: float(c.value_and_grad(th)[0])  # noqa: E731  (the full nonlinear solve)
    for key in c.scales:
        for _ in range(2):
            i = tuple(int(rng.integers(n)) for n in c.theta[key].shape)
            eps = 1e-4 * c.scales[key]
            plus, minus = (value({**c.theta, key: c.theta[key].at[i].add(s * eps)}) for s in (1, -1))
            fd = (plus - minus) / (2 * eps)
            scale = float(jnp.abs(g[key]).max())
            assert float(g[key][i]) == pytest.approx(fd, rel=1e-6, abs=1e-7 * scale), (key, i)


def hvp_program(c: Case):
    """Compiled Hessian-vector product of the misfit (forward over reverse)."""

    def misfit(th):
        return 0.5 * jnp.sum((c.solver.displacement(th) - c.target) ** 2)

    return jax.jit(lambda th, v: jax.jvp(jax.grad(misfit), (th,), (v,))[1])


@pytest.mark.parametrize("name", ["plane-strain", pytest.param("plane-stress", marks=pytest.mark.slow)])
def test_hessian_vector_product_matches_gradient_differences(name):
    c = case(name)
    v = direction(c, c.scales, rng_for(name, "hvp"))
    Hv = hvp_program(c)(c.theta, v)
    eps = 1e-4
    gp, gm = (c.value_and_grad(jax.tree.map(lambda a, b: a + s * eps * b, c.theta, v))[1] for s in (1, -1))
    for key in c.scales:
        fd = (gp[key] - gm[key]) / (2 * eps)
        scale = max(float(jnp.abs(fd).max()), 1e-300)
        assert float(jnp.abs(Hv[key] - fd).max()) < 1e-5 * scale, key


# ====================================================================== batches
@pytest.mark.parametrize("method", ["vmap", "map"])
def test_batch_of_moduli_matches_separate_solves(method):
    c = case("plane-strain")
    moduli = jnp.asarray(np.linspace(5.0, 40.0, 8)[:, None] * rng_for("batch").uniform(0.8, 1.2, c.theta["E"].shape))
    U = batch_displacement(c.solver, batched=["E"], method=method)({**c.theta, "E": moduli})
    assert U.shape == (8,) + c.target.shape
    for k in range(8):
        u, _ = c.jvp({**c.theta, "E": moduli[k]}, zeros(c.theta))
        np.testing.assert_allclose(U[k], u, rtol=0, atol=1e-10 * float(jnp.abs(u).max()))
    assert float(jnp.abs(U[0] - U[-1]).max()) > 1e-3  # the members differ


# ====================================================================== geometry
def test_reference_shapes_give_the_reference_mesh():
    c = case("plane-stress")
    th = with_geometry(c.theta, c.morph, c.morph.params0)
    np.testing.assert_allclose(th["X"], c.solver.problem.mesh.nodes, atol=1e-12)
    assert check_geometry(c.solver.problem.mesh, th["X"]) == pytest.approx(1.0)


def test_morph_that_would_invert_raises():
    c = case("plane-stress")
    mesh = c.solver.problem.mesh
    p = np.array(c.morph.params0)
    p[0, 2] += 2.0  # a wider hole squeezes its neighbours but keeps them valid
    assert 0 < check_geometry(mesh, c.morph(p)) < 1
    p[0, :2] = [4.0, 25.0]  # hole centre pushed into the outline's corner
    with pytest.raises(jf.InvertedElementError, match="scale the change"):
        check_geometry(mesh, with_geometry(c.theta, c.morph, p)["X"])


@pytest.mark.slow
def test_gradient_through_with_geometry_end_to_end():
    """jax.grad through with_geometry and the solver in one program equals the chained gradient."""
    c = case("plane-stress")

    def misfit(p):
        return 0.5 * jnp.sum((c.solver.displacement(with_geometry(c.theta, c.morph, p)) - c.target) ** 2)

    p0 = jnp.asarray(c.morph.params0)
    g = jax.jit(jax.grad(misfit))(p0)
    np.testing.assert_allclose(g, geometry_functions(c)[0](p0)[1], rtol=1e-10, atol=1e-12 * float(jnp.abs(g).max()))
