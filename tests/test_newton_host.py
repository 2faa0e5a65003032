"""Newton's loop on the host (jaxfem.newton_host) against the one jitted program
(jaxfem.newton.newton_solve, ``NONRIGID_NEWTON=jit``): the same equilibrium, counters, failures,
tangents and adjoint; and a second process that solves, differentiates and adjoins with a host
linear solver compiles nothing (every program of the host loop is kept by the persistent cache)."""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import jaxfem as jf
from jaxfem.cache import CACHE_DIR_ENV, CACHE_ENV
from jaxfem.linsolve import available
from jaxfem.newton_host import NEWTON_ENV

ROOT = Path(__file__).resolve().parent.parent
HOST = "pardiso" if "pardiso" in available() else "superlu"
COUNTERS = ("status", "steps", "attempts", "cutbacks", "iterations", "fail_step")


def _sheet(rng, stretch):
    """A plane-stress neo-Hookean sheet, clamped left, pulled right by ``stretch`` of its width,
    with a random stiffness field."""
    mesh = jf.rectangle(0, 0, 10, 6, int(rng.integers(8, 12)), int(rng.integers(5, 8)))
    fixed = np.concatenate([jf.dofs(mesh, mesh.side("left")), jf.dofs(mesh, mesh.side("right"))])
    pb = jf.Problem(mesh, "neo-hookean", "plane-stress", fixed=fixed)
    E = np.exp(rng.normal(np.log(10.0), 0.3, mesh.n_cells))
    return pb, pb.params(E=E, nu=0.3, u_D=pb.prescribe(lambda X: stretch * X * [1.0, 0.0]))


def _both(monkeypatch, make):
    out = {}
    for mode in ("jit", "host"):
        monkeypatch.setenv(NEWTON_ENV, mode)
        out[mode] = make()
    return out["jit"], out["host"]


@pytest.mark.parametrize("options", [jf.NewtonOptions(), jf.NewtonOptions(max_iter=2)])
def test_the_host_loop_makes_the_jitted_loops_steps(monkeypatch, options):
    """A hard pull (cut back at least once with few corrections allowed): the same equilibrium
    and the same load steps, attempts, cut-backs and iterations."""
    rng = np.random.default_rng(int.from_bytes(os.urandom(4), "little"))
    pb, theta = _sheet(rng, rng.uniform(0.8, 1.5))
    jit, host = _both(monkeypatch, lambda: jf.Solver(pb, HOST, options).solve(theta))
    for k in COUNTERS:
        assert int(jit.info[k]) == int(host.info[k]), k
    if options.max_iter == 2:
        assert int(host.info["cutbacks"]) >= 1
    np.testing.assert_allclose(host.u, jit.u, rtol=0, atol=1e-9 * np.abs(jit.u).max())
    np.testing.assert_allclose(host.info["residual_log"], jit.info["residual_log"], rtol=1e-3, atol=1e-13)


def test_a_failure_is_the_same_failure(monkeypatch):
    """An iteration-starved solve fails alike (the same error message: step, load factor, reason)."""
    pb, theta = _sheet(np.random.default_rng(3), 0.8)
    opts = jf.NewtonOptions(max_iter=1, min_step=0.25)
    errors = []
    for mode in ("jit", "host"):
        monkeypatch.setenv(NEWTON_ENV, mode)
        with pytest.raises(jf.SolverError) as e:
            jf.Solver(pb, HOST, opts).solve(theta)
        errors.append(str(e.value))
    assert errors[0] == errors[1]


def test_tangents_and_adjoint_are_the_jitted_programs(monkeypatch):
    """tangents_at along random directions (every parameter moved) and the adjoint of a random
    cotangent: the same as the jitted programs', and the adjoint is the tangents' transpose."""
    rng = np.random.default_rng(int.from_bytes(os.urandom(4), "little"))
    pb, theta = _sheet(rng, 0.2)
    free = pb.free_mask.reshape(-1, 2)
    dirs = {k: rng.normal(size=(3,) + np.shape(v)) for k, v in theta.items()}
    dirs["X"] *= 0.1 * free  # move the interior nodes only
    g = rng.normal(size=(pb.mesh.n_nodes, 2))

    def run():
        s = jf.Solver(pb, HOST)
        _, state = s.solve_for_adjoint(theta)
        return np.asarray(s.tangents_at(state, dirs)), s.adjoint(state, g)

    (du_j, adj_j), (du_h, adj_h) = _both(monkeypatch, run)
    np.testing.assert_allclose(du_h, du_j, rtol=0, atol=1e-9 * np.abs(du_j).max())
    for k in adj_j:
        np.testing.assert_allclose(adj_h[k], adj_j[k], rtol=0, atol=1e-9 * np.abs(adj_j[k]).max(initial=1e-300))
    lhs = np.einsum("kni,ni->k", du_h, g)
    rhs = sum(dirs[k].reshape(3, -1) @ np.asarray(adj_h[k]).reshape(-1) for k in dirs)
    np.testing.assert_allclose(lhs, rhs, rtol=1e-8)


PROGRAM = """
import numpy as np, jaxfem as jf
mesh = jf.rectangle(0, 0, 10, 6, 9, 5)
fixed = np.concatenate([jf.dofs(mesh, mesh.side("left")), jf.dofs(mesh, mesh.side("right"))])
pb = jf.Problem(mesh, "neo-hookean", "plane-stress", fixed=fixed)
theta = pb.params(E=10.0, nu=0.3, u_D=pb.prescribe(lambda X: 0.3 * X * [1.0, 0.0]))
s = jf.Solver(pb, "%s")
u, state = s.solve_for_adjoint(theta)
s.tangents_at(state, {k: np.ones((2,) + np.shape(v)) for k, v in theta.items()})
s.adjoint(state, np.ones_like(np.asarray(u)))
n = jf.compile_counts()
print(n["compiled"], n["cached"] + n["kept"], n["kept"])
"""


def test_a_second_process_compiles_nothing(tmp_path):
    env = {k: v for k, v in os.environ.items() if k not in (CACHE_ENV, NEWTON_ENV, "JAX_COMPILATION_CACHE_DIR")}
    env[CACHE_DIR_ENV] = str(tmp_path / "programs")
    counts = []
    for _ in range(2):
        out = subprocess.run([sys.executable, "-c", PROGRAM % HOST], cwd=ROOT, env=env, capture_output=True,
                             text=True, timeout=300)
        assert out.returncode == 0, out.stderr
        counts.append([int(x) for x in out.stdout.split()[-3:]])
    (compiled1, _, _), (compiled2, cached2, kept2) = counts
    # every program loaded, the host loop's kernels whole (jaxfem.executables: neither traced nor lowered)
    assert compiled1 > 0 and compiled2 == 0 and cached2 >= compiled1 and kept2 >= 3, counts
