"""Newton's quadratic convergence, seen in the solver's log, and the solver's error cases.

Quadratic convergence: with an exact tangent, r_{k+1} ~ C r_k^2, so log r_{k+1} / log r_k -> 2 as
r_k -> 0 (the first ratios are above 2 when C < 1). Checked on a neo-Hookean block clamped on one
end and pulled by a dead load to about 20 % stretch (non-homogeneous), in plane strain, plane
stress (whose tangent is the Schur complement on the out-of-plane stretch: a wrong condensation
would show as linear convergence, ratios near 1) and 3D. A displacement-driven stretch is a poor
probe: the consistent predictor already lands within 1e-4 and two corrections reach round-off.

Error cases: an unconstrained body (ProblemError naming the free rigid modes), an inverted cell
(InvertedElementError), an iteration-starved solve (SolverError with step, load factor and reason)
and a prescribed displacement that crushes a block through itself, which no equilibrium satisfies.
"""

import functools

import numpy as np
import pytest

import jaxfem as jf
from tests._verify_util import pulled_block


def quadratic_rates(log, floor=1e-14):
    """log r_{k+1} / log r_k for consecutive corrections of one load step, in the asymptotic
    range (r_k < 1e-2) and above round-off (r_{k+1} > floor, where the ratio only measures the
    floor)."""
    rates = []
    for (s0, r0), (s1, r1) in zip(log, log[1:]):
        if s0 == s1 and r0 < 1e-2 and r1 > floor:
            rates.append(np.log(r1) / np.log(r0))
    return np.array(rates)


@pytest.mark.parametrize("kinematics", ["plane-strain", "plane-stress", pytest.param("solid", marks=pytest.mark.slow)])
def test_newton_converges_quadratically(kinematics):
    *_, sol = pulled_block(kinematics)
    log = sol.newton_log()
    assert log[-1][1] < 1e-11
    rates = quadratic_rates(log)
    assert len(rates) >= 2, log
    assert np.all((rates > 1.7) & (rates < 2.6)), (rates, log)
    assert abs(rates[-1] - 2) < 0.25 and abs(rates[-1] - 2) < abs(rates[0] - 2), (rates, log)


# ====================================================================== error cases
def test_unconstrained_body_raises_problem_error_naming_rigid_modes():
    mesh = jf.rectangle(0.0, 0.0, 2.0, 1.0, 4, 2, "quad4")
    with pytest.raises(jf.ProblemError, match="rigid modes") as info:
        jf.Problem(mesh, "neo-hookean", "plane-strain")
    assert "3 of 3" in str(info.value)
    # rollers on the left edge leave the vertical translation free: the message says which
    with pytest.raises(jf.ProblemError, match="translation y"):
        jf.Problem(mesh, "neo-hookean", "plane-strain", fixed=jf.dofs(mesh, mesh.side("left"), 0))
    box = jf.box(0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1, 1, 1, "hex8")
    with pytest.raises(jf.ProblemError, match="6 of 6 rigid modes"):
        jf.Problem(box, "neo-hookean", "solid")


def test_inverted_mesh_raises_inverted_element_error():
    mesh = jf.rectangle(0.0, 0.0, 1.0, 1.0, 3, 3, "tri3")
    cells = mesh.cells.copy()
    cells[4] = cells[4, ::-1]  # one clockwise triangle
    with pytest.raises(jf.InvertedElementError, match="non-positive Jacobian"):
        jf.Problem(jf.Mesh(mesh.nodes, cells, "tri3"), "neo-hookean", fixed=jf.dofs(mesh, mesh.side("left")))
    # moving an interior node across its neighbours folds the cells around it
    X = mesh.nodes.copy()
    X[5] += [0.6, 0.0]
    with pytest.raises(jf.InvertedElementError):
        mesh.with_nodes(X)


@functools.lru_cache(maxsize=None)
def squeezed_block(max_iter=20):
    """A neo-Hookean unit square (quad4, plane strain) clamped at the bottom; the top edge's dofs
    are prescribed. Returns ``(mesh, problem, solver)``."""
    mesh = jf.rectangle(0.0, 0.0, 1.0, 1.0, 4, 4, "quad4")
    fixed = np.concatenate([jf.dofs(mesh, mesh.side("bottom")), jf.dofs(mesh, mesh.side("top"))])
    problem = jf.Problem(mesh, "neo-hookean", "plane-strain", fixed=fixed)
    options = jf.NewtonOptions(max_iter=max_iter, min_step=1 / 16)
    return mesh, problem, jf.Solver(problem, options=options)


def squeeze(problem, mesh, dy):
    target = np.zeros((mesh.n_nodes, 2))
    target[mesh.side("top"), 1] = dy
    return problem.params(E=1.0, nu=0.3, u_D=problem.prescribe(target))


def test_solver_error_reports_the_failing_load_step():
    # two Newton corrections per step are too few for an 80 % squeeze: load steps are cut back
    # until the increment is below min_step, part of the way to the full load
    mesh, problem, solver = squeezed_block(max_iter=2)
    theta = squeeze(problem, mesh, -0.8)
    with pytest.raises(jf.SolverError) as info:
        solver.solve(theta)
    e = info.value
    assert e.reason == "no-convergence"
    assert isinstance(e.step, int) and e.step >= 1
    assert 0.0 < e.load_factor < 1.0
    assert f"load step {e.step + 1}" in str(e) and f"{e.load_factor:.4g}" in str(e)
    # the reported load factor was reached: that much of the load is solvable
    u = solver.solve(squeeze(problem, mesh, -0.8 * e.load_factor)).u
    assert np.isfinite(np.asarray(u)).all()


def test_crushing_displacement_raises_solver_error():
    # the top edge pushed 1.2 x the height down, through the clamped bottom: no equilibrium
    mesh, problem, solver = squeezed_block()
    with pytest.raises(jf.SolverError) as info:
        solver.solve(squeeze(problem, mesh, -1.2))
    e = info.value
    assert e.reason in ("inverted-element", "no-convergence", "singular-tangent", "nan")
    assert e.step >= 0 and 0.0 <= e.load_factor < 1.0 / 1.2
    assert f"load step {e.step + 1}" in str(e)


@pytest.mark.parametrize("dy", [-0.99, -1.2])
def test_returned_solution_satisfies_prescribed_displacements(dy):
    mesh, problem, solver = squeezed_block()
    theta = squeeze(problem, mesh, dy)
    try:
        u = np.asarray(solver.solve(theta).u)
    except jf.SolverError:
        return  # refusing is fine; returning a wrong equilibrium is not
    gap = np.abs(u.ravel()[problem.fixed] - np.asarray(theta["u_D"])).max()
    assert gap < 1e-10, f"prescribed dofs off by {gap:.3g} (top edge at {u[mesh.side('top'), 1].min():.4g}, not {dy})"


def test_prescribed_displacements_hold_when_the_predictor_is_not_damped():
    # control case: a feasible 90 % squeeze reaches its Dirichlet data exactly
    mesh, problem, solver = squeezed_block()
    theta = squeeze(problem, mesh, -0.9)
    u = np.asarray(solver.solve(theta).u)
    assert np.abs(u.ravel()[problem.fixed] - np.asarray(theta["u_D"])).max() < 1e-12
