"""The equilibrium's derivatives along the prescribed values alone, from the converged tangent on
the host (jaxfem.Solver.solve_with_prescribed_tangents: the drive Jacobian of the diagnosis's
covariance), equal the tangents program's (solve_with_tangents) for the host solvers; PARDISO
solves several right-hand sides in one call as it solves each alone. A small sheet of random
moduli, pulled and sheared by random amounts (seeded)."""

import numpy as np
import pytest

import jaxfem as jf
from jaxfem.linsolve import available


def _sheet(rng, linear_solver):
    mesh = jf.rectangle(0, 0, 100, 60, int(rng.integers(8, 12)), int(rng.integers(5, 8)), "tri6")
    fixed = np.concatenate([jf.dofs(mesh, mesh.side("left")), jf.dofs(mesh, mesh.side("right"))])
    problem = jf.Problem(mesh, "neo-hookean", "plane-stress", fixed=fixed)
    stretch, shear = rng.uniform(5, 15), rng.uniform(-3, 3)
    pull = problem.prescribe(lambda X: np.where(X[:, :1] > 50, [stretch, shear], 0.0))
    theta = problem.params(E=rng.uniform(50, 100, mesh.n_cells), nu=0.3, thickness=1.0, u_D=pull)
    return jf.Solver(problem, linear_solver), theta


@pytest.mark.parametrize("linear_solver", [s for s in ("pardiso", "superlu") if s in available()])
def test_prescribed_tangents_equal_the_tangents_program(linear_solver):
    rng = np.random.default_rng(31)
    solver, theta = _sheet(rng, linear_solver)
    m = int(rng.integers(9, 13))  # more than one batch of the tangents program
    du_D = rng.normal(size=(m, len(solver.problem.fixed)))
    zero = {k: np.zeros((m,) + np.shape(v)) for k, v in theta.items() if k != "u_D"}
    u_ref, du_ref, _ = solver.solve_with_tangents(theta, {**zero, "u_D": du_D})
    u, du, info = solver.solve_with_prescribed_tangents(theta, du_D)
    assert int(info["status"]) == 0
    np.testing.assert_array_equal(np.asarray(u), np.asarray(u_ref))
    np.testing.assert_allclose(np.asarray(du), np.asarray(du_ref), rtol=0, atol=1e-10 * np.abs(du_ref).max())
    np.testing.assert_allclose(np.asarray(du).reshape(m, -1)[:, solver.problem.fixed], du_D, atol=1e-12)


@pytest.mark.skipif("pardiso" not in available(), reason="PARDISO (pypardiso) not installed")
def test_pardiso_solves_many_right_hand_sides_as_each_alone():
    rng = np.random.default_rng(37)
    solver, theta = _sheet(rng, "pardiso")
    _, _, vals = solver._solve_padded(theta, None)
    n, nnz = solver.problem.n_dofs, solver.pattern.nnz
    K = np.asarray(vals)[:nnz] * solver._keep_host + solver._diag_fixed_host
    B = rng.normal(size=(n, int(rng.integers(3, 7))))
    together = solver._lin._cache(K, B)
    alone = np.stack([solver._lin._cache(K, np.ascontiguousarray(b)) for b in B.T], axis=1)
    np.testing.assert_allclose(together, alone, rtol=0, atol=1e-12 * np.abs(alone).max())
