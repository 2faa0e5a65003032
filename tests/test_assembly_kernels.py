"""The assembly's fast paths give the same numbers as the plain ones.

- ``element_matrices`` writes the element-matrix contraction term by term (cells on the minor
  axis) for elements with few quadrature terms; it must equal the ``einsum`` of the definition
  for every element kind, on random shape gradients and random (non-symmetric) tangents.
- The material state (the plane-stress out-of-plane stretch kept between evaluations): starting
  the stretch's Newton iteration from a converged stretch, from a nearby state's stretch or from
  nothing must give the same residual and tangent (to rounding) and the same converged stretch.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxfem as jf
from jaxfem.assembly import element_matrices
from jaxfem.elements import get_element


@pytest.mark.parametrize("element", ["tri3", "tri6", "quad4", "tet4", "hex8"])
def test_element_matrices_equal_the_einsum_definition(element):
    el = get_element(element)
    nq, npc, dim = el.dN.shape
    rng = np.random.default_rng(7)
    cells = 37
    dNdX = jnp.asarray(rng.normal(size=(cells, nq, npc, dim)))
    A = jnp.asarray(rng.normal(size=(cells, nq) + (dim,) * 4))
    w = jnp.asarray(rng.random((cells, nq)))
    ref = jnp.einsum("cqaK,cqjLiK,cqbL,cq->caibj", dNdX, A, dNdX, w)
    got = jax.jit(element_matrices)(dNdX, A, w)
    assert got.shape == ref.shape
    np.testing.assert_allclose(got, ref, rtol=1e-13, atol=1e-13 * float(jnp.abs(ref).max()))


def _sheet(kinematics):
    mesh = jf.rectangle(0.0, 0.0, 10.0, 6.0, 5, 3, "tri3")
    left, right = mesh.side("left"), mesh.side("right")
    fixed = np.concatenate([jf.dofs(mesh, left, [0, 1]), jf.dofs(mesh, right, 0)])
    pb = jf.Problem(mesh, "neo-hookean", kinematics, fixed=fixed)
    theta = pb.params(E=2.0, nu=0.3, u_D=pb.prescribe(lambda X: 0.25 * X * np.array([1.0, 0.0])))
    return jf.Solver(pb, linear_solver="dense"), theta


@pytest.mark.parametrize("kinematics", ["plane-stress", "plane-strain"])
def test_material_state_start_does_not_change_the_result(kinematics):
    solver, theta = _sheet(kinematics)
    u = solver.solve(theta).u
    rng = np.random.default_rng(3)
    u_near = u + 0.01 * jnp.asarray(rng.normal(size=u.shape))  # strains change by ~1e-2
    p, X, t = solver._split(theta)
    asm, arrays, nnz = solver.assembler, solver.arrays, solver.pattern.nnz
    rt = jax.jit(lambda u, s: asm.residual_and_tangent(u, X, p, t, arrays, nnz, s))
    rd = jax.jit(lambda u, s: asm.residual_and_min_det(u, X, p, t, arrays, s))
    cold = jnp.full((solver.problem.mesh.n_cells, 1), jnp.nan)

    R0, K0, lam = rt(u, cold)
    if kinematics == "plane-stress":  # the sheet thins under 25 % stretch
        assert float(lam.max()) < 0.99 and float(lam.min()) > 0.8
    for state in (lam, lam * (1 + 1e-3), jnp.ones_like(lam)):  # converged, nearby, far
        R, K, lam2 = rt(u, state)
        np.testing.assert_allclose(R, R0, rtol=0, atol=1e-12 * float(jnp.abs(R0).max()))
        np.testing.assert_allclose(K, K0, rtol=0, atol=1e-12 * float(jnp.abs(K0).max()))
        np.testing.assert_allclose(lam2, lam, rtol=1e-14)
    # a nearby displacement from the old state = from nothing
    Rn0, d0, lamn0 = rd(u_near, cold)
    Rn, d, lamn = rd(u_near, lam)
    np.testing.assert_allclose(Rn, Rn0, rtol=0, atol=1e-12 * float(jnp.abs(Rn0).max()))
    np.testing.assert_allclose(lamn, lamn0, rtol=1e-14)
    assert float(d) == pytest.approx(float(d0), rel=1e-15)
