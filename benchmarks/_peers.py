"""Peer solvers of benchmarks/forward.py: scikit-fem in-process, torch-fem in a child process.

- :func:`skfem_plane_strain`: scikit-fem's Newton for a compressible neo-Hookean solid, written
  with its ``BilinearForm`` / ``LinearForm`` as in its hyperelasticity example (docs/examples/ex43),
  in 2D: a 2x2 F with F33 = 1 is plane strain.
- torch-fem runs in a child process (``python -m benchmarks _peers torchfem ...``): torch ships its
  own MKL and OpenMP runtime, which should not share a process with JAX's and pypardiso's; the
  child also gets its own thread count and a time limit. torch-fem imports pyvista for plotting
  only: the child stubs it out (pyvista pulls in VTK, a few hundred MB).

The standalone sparse direct solves are in ``_direct.py``, the timing helpers in ``_timing.py``.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse.linalg as spla

from benchmarks._subprocess import command, environment
from benchmarks._timing import best_of, loadavg

HERE = Path(__file__).resolve().parent


# ====================================================================== scikit-fem (2D plane strain)
def skfem_plane_strain(nodes, cells, fixed, u_D, E, nu, n_steps=1, rtol=1e-9, utol=1e-4, max_iter=20,
                       repeats=3, budget=120.0) -> dict:
    """Compressible neo-Hookean plane strain with scikit-fem (P1 triangles, the given mesh).

    The Newton loop follows scikit-fem's hyperelasticity example (ex43): the prescribed increment
    goes in through ``condense(K, -f, x=du_D, D=D)``, then ``f`` and ``K`` are reassembled. It stops
    on jaxfem's criterion (free residual <= rtol x reactions and |du| <= utol |u|), so the count of
    linear solves is comparable. ``fixed``/``u_D`` use jaxfem's dof numbering (node * 2 + comp).
    """
    from skfem import Basis, BilinearForm, ElementTriP1, ElementVector, LinearForm, MeshTri, condense, solve
    from skfem.helpers import ddot, det, grad, identity, inv, mul, trace, transpose

    mu = E / (2 * (1 + nu))
    lmbda = E * nu / ((1 + nu) * (1 - 2 * nu))
    t0 = time.perf_counter()
    mesh = MeshTri(np.ascontiguousarray(nodes.T), np.ascontiguousarray(cells.T))
    basis = Basis(mesh, ElementVector(ElementTriP1()), intorder=1)  # P1: one point is exact
    setup = time.perf_counter() - t0

    def deformation_gradient(w):
        dudX = grad(w["displacement"])
        F = dudX + identity(dudX)
        return F, inv(F)

    @LinearForm
    def L(v, w):
        F, iF = deformation_gradient(w)
        dF = grad(v)
        lnJ = np.log(det(F))
        return mu * ddot(F, dF) + (lmbda * lnJ - mu) * ddot(transpose(iF), dF)

    @BilinearForm
    def a(u, v, w):
        F, iF = deformation_gradient(w)
        DF, dF = grad(u), grad(v)
        dFiF, DFiF = mul(dF, iF), mul(DF, iF)
        lnJ = np.log(det(F))
        return (mu * ddot(DF, dF) - (lmbda * lnJ - mu) * ddot(transpose(dFiF), DFiF)
                + lmbda * trace(dFiF) * trace(DFiF))

    node, comp = np.asarray(fixed) // 2, np.asarray(fixed) % 2
    D = basis.nodal_dofs[comp, node]
    free = np.ones(basis.N, bool)
    free[D] = False
    target = np.zeros(basis.N)
    target[D] = u_D

    def superlu(A, b, **kw):
        return spla.spsolve(A, b, use_umfpack=False)

    def run():
        u = basis.zeros()
        uv = basis.interpolate(u)
        f, K = L.assemble(basis, displacement=uv), a.assemble(basis, displacement=uv)
        solves, t_solve, t_asm = 0, 0.0, 0.0
        for step in range(n_steps):
            c = (step + 1.0) / n_steps
            for _ in range(max_iter):
                du_D = np.zeros(basis.N)
                du_D[D] = c * target[D] - u[D]
                t = time.perf_counter()
                du = solve(*condense(K, -f, x=du_D, D=D), solver=superlu)
                t_solve += time.perf_counter() - t
                u = u + du
                solves += 1
                t = time.perf_counter()
                uv = basis.interpolate(u)
                f, K = L.assemble(basis, displacement=uv), a.assemble(basis, displacement=uv)
                t_asm += time.perf_counter() - t
                res, scale = np.linalg.norm(f[free]), max(np.linalg.norm(f[~free]), 1e-300)
                if res <= rtol * scale and np.linalg.norm(du) <= utol * np.linalg.norm(u):
                    break
            else:
                raise RuntimeError(f"scikit-fem Newton did not converge in load step {step + 1}")
        return u, solves, t_solve, t_asm

    t, times, (u, solves, t_solve, t_asm) = best_of(run, repeats, budget=budget)
    U = np.stack([u[basis.nodal_dofs[0]], u[basis.nodal_dofs[1]]], 1)
    return {"seconds": t, "all": times, "setup_seconds": setup, "iterations": solves,
            "steps": n_steps, "linear_solve_seconds": t_solve, "assembly_seconds": t_asm,
            "seconds_per_iteration": t / solves, "load": loadavg(), "u": U}


# ====================================================================== torch-fem (child process)
def torchfem_run(job: dict, timeout: float, threads: int = 1) -> dict:
    """Run one torch-fem job in a child process (see :func:`_torchfem_child`); returns its JSON."""
    env = environment(OMP_NUM_THREADS=str(threads), MKL_NUM_THREADS=str(threads))
    env.pop("PYPARDISO_MKL_RT", None)
    path = HERE / "results" / f".torchfem_job_{os.getpid()}.npz"
    np.savez(path, **{k: v for k, v in job.items() if isinstance(v, np.ndarray)})
    meta = {k: v for k, v in job.items() if not isinstance(v, np.ndarray)}
    cmd = command("_peers", "torchfem", path, json.dumps(meta), threads)
    try:
        out = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env)
    except subprocess.TimeoutExpired:
        return {"error": f"did not finish within {timeout:.0f} s (killed)", "threads": threads}
    finally:
        path.unlink(missing_ok=True)
    lines = [ln for ln in out.stdout.splitlines() if ln.startswith("RESULT ")]
    if out.returncode != 0 or not lines:
        return {"error": (out.stderr or out.stdout)[-600:], "threads": threads}
    return json.loads(lines[-1][len("RESULT "):])


def _import_torchfem():
    """Import torch-fem with pyvista (plotting only) replaced by a stub."""
    from unittest import mock

    try:
        import pyvista  # noqa: F401
    except ImportError:
        stub = mock.MagicMock()
        sys.modules["pyvista"] = stub
        sys.modules["pyvista.plotting"] = stub.plotting
    import torchfem
    import torchfem.sparse

    return torchfem


def _torchfem_child(npz: str, meta: dict, threads: int) -> dict:
    import torch

    torch.set_num_threads(threads)
    torch.set_default_dtype(torch.float64)
    tf = _import_torchfem()
    from torchfem import Solid
    from torchfem.materials import Hyperelastic3D

    data = np.load(npz)
    E, nu = meta["E"], meta["nu"]
    MU = E / (2.0 * (1.0 + nu))
    LBD = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))

    def psi(F, params):  # the energy of torch-fem's benchmarks/hyperelasticity.py
        C = F.transpose(-1, -2) @ F
        logJ = 0.5 * torch.logdet(C)
        return params[0] / 2 * (torch.trace(C) - 3.0) - params[0] * logJ + params[1] / 2 * logJ**2

    counter = {"solves": 0, "krylov": 0}
    orig = tf.sparse.sparse_solve

    def counting(*a, **k):
        out = orig(*a, **k)
        counter["solves"] += 1
        counter["krylov"] += int(out[3] or 0)
        return out

    tf.sparse.sparse_solve = counting
    documented = meta["kind"] == "documented"
    if documented:  # torch-fem's benchmarks/hyperelasticity.py, get_stretch(N) and setup(N)
        from torchfem.mesh import cube_hexa

        N, U = meta["N"], meta["U"]
        nodes, elements = cube_hexa(N, N, N)
        cons = torch.zeros(len(nodes), 3, dtype=torch.bool)
        cons[nodes[:, 0] == 0.0, 0] = True
        cons[nodes[:, 0] == 1.0, 0] = True
        cons[nodes[:, 1] == 0.5, 1] = True
        cons[nodes[:, 2] == 0.5, 2] = True
        disp = torch.zeros(len(nodes), 3)
        disp[nodes[:, 0] == 1.0, 0] = U
        right = nodes[:, 0] == 1.0
        lam = torch.logspace(0, math.log10(1.0 + U), meta["n_inc"])
        increments = (lam - 1.0) / U
    else:
        nodes, elements = torch.tensor(data["nodes"]), torch.tensor(data["cells"])
        cons = torch.tensor(data["constraints"])
        disp = torch.zeros(len(nodes), 3)
        disp[cons] = torch.tensor(data["u_D"])
        right = torch.tensor(data["right"])
        increments = torch.tensor(data["increments"])

    def build():
        params = torch.tensor([MU, LBD], requires_grad=documented)
        box = Solid(nodes, elements, Hyperelastic3D(psi, params))
        box.constraints = cons.clone()
        box.displacements = disp.clone()
        return box, params

    times, result = [], None
    for _ in range(meta.get("repeats", 1)):
        box, params = build()
        counter.update(solves=0, krylov=0)
        t = time.perf_counter()
        if documented:  # as torch-fem's benchmark: parameters declared differentiable
            u, f, *_ = box.solve(increments=increments, differentiable_parameters=params)
        else:
            u, f, *_ = box.solve(increments=increments)
        times.append(time.perf_counter() - t)
        result = (u, f, dict(counter))
        if sum(times) > meta.get("budget", 60.0):
            break
    u, f, counts = result
    method = tf.sparse.resolve_method(box.n_dofs, None, True)
    pre = tf.sparse.resolve_preconditioner(method, "cpu", None)
    return {"seconds": min(times), "all": times, "dofs": 3 * len(nodes), "increments": len(increments) - 1,
            "iterations": counts["solves"], "krylov_iterations": counts["krylov"],
            "reaction_x": float(f[right, 0].sum()), "u_right_x_mean": float(u[right, 0].mean()),
            "method": method, "library": tf.sparse.resolve_library(method, "cpu", pre),
            "preconditioner": pre, "threads": threads, "torch": torch.__version__,
            "torchfem": __import__("importlib.metadata").metadata.version("torch-fem")}


if __name__ == "__main__":
    if len(sys.argv) == 5 and sys.argv[1] == "torchfem":
        res = _torchfem_child(sys.argv[2], json.loads(sys.argv[3]), int(sys.argv[4]))
        print("RESULT " + json.dumps(res))
    else:
        sys.exit("usage: python -m benchmarks _peers torchfem JOB.npz META_JSON THREADS (used by forward.py)")
