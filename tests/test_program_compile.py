"""jaxfem.program.Program compiles a new shape outside its lock (so one thread's compile does
not hold up another's solve on the same program) and only once; the run after it compiles
nothing and gives the same displacements. A small sheet, its load drawn under a seed."""

import threading

import jax
import numpy as np

import jaxfem as jf


def _compiles():
    seen = []
    jax.monitoring.register_event_duration_secs_listener(
        lambda event, duration, **kw: seen.append(event) if event.endswith("backend_compile_duration") else None)
    return seen


def test_a_new_shape_compiles_outside_the_lock_once():
    rng = np.random.default_rng(41)
    mesh = jf.rectangle(0, 0, 30, 20, 7, 5)
    fixed = np.concatenate([jf.dofs(mesh, mesh.side("left")), jf.dofs(mesh, mesh.side("right"))])
    problem = jf.Problem(mesh, "neo-hookean", "plane-stress", fixed=fixed)
    pull = problem.prescribe(lambda X: np.where(X[:, :1] > 15, [rng.uniform(1, 3), rng.uniform(-1, 1)], 0.0))
    theta = problem.params(E=rng.uniform(50, 100, mesh.n_cells), nu=0.3, thickness=1.0, u_D=pull)
    solver = jf.Solver(problem, "superlu")
    prog = solver.program
    args = (*solver._pad(theta, *solver._start(theta, None)), solver.padded_arrays)
    seen = _compiles()
    with prog.lock:  # another thread holds the program (a solve of another hypothesis)
        worker = threading.Thread(target=prog.compile, args=("newton", *args))
        worker.start()
        worker.join(timeout=300)
        assert not worker.is_alive(), "the compile waited for the program's lock"
    n = len(seen)
    prog.compile("newton", *args)  # done already: nothing
    u = solver.displacement(theta)  # runs what was compiled
    assert len(seen) == n, "the run after the compile compiled again"
    want = jf.Solver(problem, "superlu").solve(theta).u
    np.testing.assert_allclose(np.asarray(u), np.asarray(want), rtol=0, atol=1e-12 * np.abs(want).max())
