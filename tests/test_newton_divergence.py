"""Load step attempts that make no progress end early and are cut back (jaxfem.newton)."""

import numpy as np

import jaxfem as jf


def _cube(n=2, U=19.0):
    """torch-fem's hyperelasticity benchmark on a coarse mesh: a unit cube stretched to 20x."""
    mesh = jf.box(0, 0, 0, 1, 1, 1, n, n, n, "hex8")
    X = mesh.nodes
    left, right = np.flatnonzero(X[:, 0] == 0), np.flatnonzero(X[:, 0] == 1)
    fixed = np.concatenate([jf.dofs(mesh, left, 0), jf.dofs(mesh, right, 0),
                            jf.dofs(mesh, np.flatnonzero(np.isclose(X[:, 1], 0.5)), 1),
                            jf.dofs(mesh, np.flatnonzero(np.isclose(X[:, 2], 0.5)), 2)])
    pb = jf.Problem(mesh, "neo-hookean", "solid", fixed=fixed)
    u = np.zeros_like(X)
    u[right, 0] = U
    return pb, pb.params(E=1000.0, nu=0.3, u_D=pb.prescribe(u))


def test_hopeless_attempts_end_early_and_reach_the_same_equilibrium():
    pb, theta = _cube()
    early = jf.Solver(pb, "superlu").solve(theta)
    full = jf.Solver(pb, "superlu", jf.NewtonOptions(diverge_after=0)).solve(theta)
    assert int(full.info["cutbacks"]) >= 1  # the full stretch in one step is too much for Newton
    np.testing.assert_allclose(np.asarray(early.u), np.asarray(full.u), rtol=0, atol=1e-8 * 19.0)
    assert int(early.info["iterations"]) < int(full.info["iterations"])
    its = early.info["step_iterations"][: int(early.info["attempts"])]
    # a failed attempt is abandoned after diverge_after corrections without progress
    assert its.max() <= 20 and np.sort(its)[: int(early.info["cutbacks"])].max() <= 2 * 2


def test_an_easy_step_is_not_abandoned():
    mesh = jf.rectangle(0, 0, 10, 6, 10, 6)
    fixed = np.concatenate([jf.dofs(mesh, mesh.side("left")), jf.dofs(mesh, mesh.side("right"))])
    pb = jf.Problem(mesh, "neo-hookean", "plane-stress", fixed=fixed)
    theta = pb.params(E=10.0, nu=0.3, u_D=pb.prescribe(lambda X: 0.2 * X * [1.0, 0.0]))
    sol = jf.Solver(pb, "superlu").solve(theta)
    assert int(sol.info["steps"]) == 1 and int(sol.info["cutbacks"]) == 0
