"""SuperLU inside jitted solves: every factorisation made and freed on one host thread, and a
matrix that is not finite never factorised.

SciPy's SuperLU leaks a factorisation freed on another thread than the one that made it; XLA runs
host callbacks on any of its threads, and a diagnosis once grew to 24 GB that way.
"""

import os
import threading

import jax
import numpy as np

import jaxfem as jf
from jaxfem.linsolve import _base, superlu


def _sheet_solver():
    mesh = jf.rectangle(0, 0, 40, 20, 16, 8)
    fixed = np.concatenate([jf.dofs(mesh, mesh.side("left")), jf.dofs(mesh, mesh.side("right"))])
    problem = jf.Problem(mesh, "neo-hookean", "plane-stress", fixed=fixed)
    solver = jf.Solver(problem, linear_solver="superlu")
    pull = problem.prescribe(lambda X: np.where(X[:, :1] > 20, [4.0, 0.0], 0.0))
    return solver, problem.params(E=10.0, nu=0.3, u_D=pull)


def test_factorisations_are_made_and_freed_on_one_thread(monkeypatch):
    made, freed = set(), set()

    class Factor:
        def __init__(self, solve):
            made.add(threading.get_ident())
            self.solve = solve

        def __call__(self, b):
            return self.solve(b)

        def __del__(self):
            freed.add(threading.get_ident())

    original = superlu.superlu_factor
    monkeypatch.setattr(superlu, "superlu_factor", lambda pattern, vals: Factor(original(pattern, vals)))
    solver, theta = _sheet_solver()
    E0 = theta["E"]
    for k in range(4):  # Newton solves, then a Jacobian (tangent solves on the vmapped directions)
        solver.solve({**theta, "E": E0 * (1 + 0.1 * k)})
    jax.jacfwd(lambda s: solver.displacement({**theta, "E": E0 * s}).sum(0))(1.0)
    assert len(made) == 1 and freed <= made, (made, freed)
    assert made != {threading.get_ident()}  # the solver's own thread, not the caller's


def test_memory_stays_flat_over_many_factorisations():
    solver, theta = _sheet_solver()
    E0 = theta["E"]
    rss = lambda: int(open(f"/proc/{os.getpid()}/statm").read().split()[1]) * os.sysconf("SC_PAGE_SIZE")  # noqa: E731
    solver.solve(theta)
    before = rss()
    for k in range(150):  # ~600 factorisations of a 300-dof matrix: ~50 MB leaked before the fix
        solver.solve({**theta, "E": E0 * (1 + 0.01 * k)})
    assert rss() - before < 20e6


def test_a_matrix_that_is_not_finite_is_not_factorised():
    calls = []
    cache = _base._FactorCache(lambda vals: calls.append(vals) or (lambda b: b), one_thread=True)
    x = cache(np.array([1.0, np.nan]), np.ones(3))
    assert np.isnan(x).all() and x.shape == (3,) and not calls
    assert np.array_equal(cache(np.array([1.0, 2.0]), np.ones(3)), np.ones(3)) and len(calls) == 1
