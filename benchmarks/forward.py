"""Forward-solve benchmark of jaxfem: neo-Hookean stretch of a sheet (2D) and a block (3D).

For a sweep of mesh sizes it measures, on this machine and in one run:

- jaxfem with each of its linear solvers (``superlu``, ``klu``, ``pardiso``; ``cg`` and ``dense`` at
  the smallest size): compile seconds (first call minus warm call), warm solve seconds (best of 3),
  Newton iterations (linear solves including the predictor), load steps, seconds per iteration;
- one factor + solve of the same tangent (jaxfem's tangent at the solution, constrained as the
  solver does) by every sparse direct solver installed here: SciPy SuperLU (its default COLAMD, and
  jaxfem's symmetric-mode options), KLU (klujax), MKL PARDISO (pypardiso, fresh solver object each
  time), CHOLMOD (scikit-sparse, when importable); each row's ``per_iteration_ratio`` spells out
  the ratio of the target (best jaxfem seconds per Newton iteration over the fastest of these
  complete factor + solves) and, for reference, the same over the numeric phases alone;
- where the time of one Newton iteration goes (the jitted residual + tangent assembly alone);
- peers: scikit-fem on the same triangle mesh in plane strain (against jaxfem in plane strain),
  and torch-fem on the same hexahedral block and on its own neo-Hookean benchmark
  (benchmarks/hyperelasticity.py of torch-fem: a unit cube stretched to 20x its length).

It writes benchmarks/results/forward.json (all numbers, the targets with pass/fail) and forward.png.

    python benchmarks/forward.py           # ~25 min on a loaded 2-core machine: 2D to 51k, 3D to 10k DOFs
    python benchmarks/forward.py --full    # adds 2D 102k-406k and 3D 29k-103k DOFs (an hour or more)
    python benchmarks/forward.py --quick   # smoke test, tiny sizes

A combination predicted to take more than --budget seconds (60) for one solve is skipped and
recorded as skipped. The machine may be shared: every timing is a best-of-N and carries the load
average when it was taken.
"""

from __future__ import annotations

import argparse
import gc
import json
import math
import os
import platform
import sys
import time
from importlib import metadata
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(HERE))

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402

import jaxfem as jf  # noqa: E402
from jaxfem.linsolve import AUTO_KLU_MAX_DOFS_2D, auto_choice, available  # noqa: E402

import _peers  # noqa: E402
from _forward_report import _json_default, flag_load, plot, targets  # noqa: E402
from _peers import best_of, loadavg  # noqa: E402

E_SHEET, NU = 83.76, 0.3
SHEET = (100.0, 60.0)             # sheet length x height; cells are squares (nx : ny = 5 : 3)
BLOCK = (2.0, 1.0, 1.0)           # block lengths; cubic cells (nx = 2 n, ny = nz = n)
STRETCH = 0.2

SIZES_2D = {"quick": [(10, 6), (40, 24)], "default": [(40, 24), (65, 39), (130, 78), (205, 123)],
            "full": [(40, 24), (65, 39), (130, 78), (205, 123), (290, 174), (410, 246), (580, 348)]}
SIZES_3D = {"quick": [3, 6], "default": [6, 11], "full": [6, 11, 16, 20, 25]}
DOC_N = {"quick": [5], "default": [5, 9], "full": [5, 9, 13]}   # torch-fem's own benchmark sizes
DOC = {"E": 1000.0, "nu": 0.3, "U": 19.0, "n_inc": 21}          # as in torch-fem's benchmark

DIRECT_FOR = {"superlu": "superlu_jaxfem", "klu": "klu", "pardiso": "pardiso_jaxfem", "cholmod": "cholmod"}


def log(*a):
    print(f"[{time.strftime('%H:%M:%S')} load {loadavg():.1f}]", *a, flush=True)


# ====================================================================== problems
def sheet(nx, ny, kinematics="plane-stress"):
    L, H = SHEET
    mesh = jf.rectangle(0, 0, L, H, nx, ny)
    left, right = mesh.side("left"), mesh.side("right")
    corner = left[np.argmin(mesh.nodes[left, 1])]
    fixed = np.concatenate([jf.dofs(mesh, left, 0), jf.dofs(mesh, right, 0), jf.dofs(mesh, [corner], 1)])
    pb = jf.Problem(mesh, "neo-hookean", kinematics, fixed=fixed)
    theta = pb.params(E=E_SHEET, nu=NU, u_D=pb.prescribe(lambda X: STRETCH * X * np.array([1.0, 0.0])))
    return pb, theta, right


def block(n):
    Lx, Ly, Lz = BLOCK
    mesh = jf.box(0, 0, 0, Lx, Ly, Lz, 2 * n, n, n, "hex8")
    X = mesh.nodes
    left, right = mesh.side("left"), mesh.side("right")
    a = np.flatnonzero((X[:, 0] == 0) & (X[:, 1] == 0) & (X[:, 2] == 0))
    b = np.flatnonzero((X[:, 0] == 0) & (np.isclose(X[:, 1], Ly)) & (X[:, 2] == 0))
    fixed = np.concatenate([jf.dofs(mesh, left, 0), jf.dofs(mesh, right, 0), jf.dofs(mesh, a, 1),
                            jf.dofs(mesh, a, 2), jf.dofs(mesh, b, 2)])
    pb = jf.Problem(mesh, "neo-hookean", "solid", fixed=fixed)
    theta = pb.params(E=E_SHEET, nu=NU, u_D=pb.prescribe(lambda X: STRETCH * X * np.array([1.0, 0, 0])))
    return pb, theta, right


def torchfem_cube(N):
    """torch-fem's benchmark problem (benchmarks/hyperelasticity.py) as a jaxfem problem: unit cube of
    (N-1)^3 hexahedra, x fixed on the left face and prescribed (U) on the right, y fixed on the plane
    y = 0.5 and z on z = 0.5, E = 1000, nu = 0.3."""
    mesh = jf.box(0, 0, 0, 1, 1, 1, N - 1, N - 1, N - 1, "hex8")
    X = mesh.nodes
    left, right = np.flatnonzero(X[:, 0] == 0), np.flatnonzero(X[:, 0] == 1)
    fixed = np.concatenate([jf.dofs(mesh, left, 0), jf.dofs(mesh, right, 0),
                            jf.dofs(mesh, np.flatnonzero(X[:, 1] == 0.5), 1),
                            jf.dofs(mesh, np.flatnonzero(X[:, 2] == 0.5), 2)])
    pb = jf.Problem(mesh, "neo-hookean", "solid", fixed=fixed)
    U = np.zeros_like(X)
    U[right, 0] = DOC["U"]
    return pb, pb.params(E=DOC["E"], nu=DOC["nu"], u_D=pb.prescribe(U)), right


# ====================================================================== jaxfem measurements
def run_jaxfem(solver, theta, repeats=3, budget=None):
    """First call, then best of ``repeats`` warm calls of ``solver.solve(theta)``."""
    t = time.perf_counter()
    sol = solver.solve(theta)
    jax.block_until_ready(sol.u)
    first = time.perf_counter() - t

    def once():
        s = solver.solve(theta)
        jax.block_until_ready(s.u)
        return s

    warm, times, sol = best_of(once, repeats, budget=budget)
    info = sol.info
    it = int(info["iterations"])
    return {"first_s": first, "warm_s": warm, "compile_s": first - warm, "all_warm_s": times,
            "iterations": it, "steps": int(info["steps"]), "cutbacks": int(info["cutbacks"]),
            "attempts": int(info["attempts"]), "per_iteration_s": warm / it, "load": loadavg()}, sol


def assembly_times(solver, u, theta, repeats=5):
    """Jitted pieces of one Newton iteration, index arrays passed as arguments (as the solver does)."""
    asm, arrays, nnz = solver.assembler, solver.arrays, solver.pattern.nnz
    p, X, t = solver._split(theta)
    U = jnp.asarray(u).reshape(X.shape)
    f_rt = jax.jit(lambda U, X, p, t, arrays: asm.residual_and_tangent(U, X, p, t, arrays, nnz))
    f_r = jax.jit(lambda U, X, p, t, arrays: asm.residual(U, X, p, t, arrays))
    f_md = jax.jit(lambda U, X, cells: asm.min_jacobian(U, X, cells))
    res = {}
    for name, fn, args in (("residual_and_tangent_s", f_rt, (U, X, p, t, arrays)),
                           ("residual_s", f_r, (U, X, p, t, arrays)),
                           ("min_jacobian_s", f_md, (U, X, arrays["cells"]))):
        tc = time.perf_counter()
        out = jax.block_until_ready(fn(*args))
        res[name.replace("_s", "_compile_s")] = time.perf_counter() - tc
        res[name], _, _ = best_of(lambda: jax.block_until_ready(fn(*args)), repeats)
        if name == "residual_and_tangent_s":
            vals = np.asarray(out[1])
    keep, diag_fixed = np.asarray(arrays["keep"]), np.asarray(arrays["diag_fixed"])
    return res, vals * keep + diag_fixed      # = Solver._constrained(tangent_values(u, theta))


class Extrapolator:
    """Predicts a solver's seconds at a new size from its last two (a power law in the dofs)."""

    def __init__(self, default_power):
        self.hist, self.p0 = {}, default_power

    def add(self, key, n, t):
        if t is not None and t > 0:
            self.hist.setdefault(key, []).append((n, t))

    def predict(self, key, n):
        h = self.hist.get(key)
        if not h or h[-1][1] < 0.25:  # below that, fixed costs dominate: no extrapolation (just run it)
            return None
        if len(h) >= 2 and h[-1][0] != h[-2][0]:
            p = math.log(h[-1][1] / h[-2][1]) / math.log(h[-1][0] / h[-2][0])
            p = min(max(p, 1.0), 3.0)
        else:
            p = self.p0
        return h[-1][1] * (n / h[-1][0]) ** p


# ====================================================================== one size of a sweep
def measure_size(pb, theta, right, args, ext: Extrapolator, label, extra_solvers=()):
    n = pb.n_dofs
    row = {"dofs": n, "cells": pb.mesh.n_cells, "nodes": pb.mesh.n_nodes}
    # jaxfem with CHOLMOD only in 2D: on the 3D block its factorisation was 7-9x slower than
    # PARDISO's, and at 28.6k DOFs it declared the tangent not positive definite (SuperLU took over
    # and ran out of memory)
    solvers = ["superlu", "klu", "pardiso", *(("cholmod",) if pb.mesh.dim == 2 else ()), *extra_solvers]
    solvers = [s for s in solvers if s in available() and (not args.solvers or s in args.solvers)]
    jax_rows, skipped, sols = {}, {}, {}

    # 1. the primary solve (gives the state whose tangent the direct solvers factor)
    pred_first = {s: ext.predict(("jaxfem", s), n) for s in solvers}
    primary = min((s for s in ("superlu", "pardiso") if s in solvers),
                  key=lambda s: pred_first[s] if pred_first[s] is not None else (0 if s == "superlu" else 1))
    order = [primary] + [s for s in solvers if s != primary]

    assembly, vals, iters = None, None, None
    for name in order:
        pred = ext.predict(("jaxfem", name), n)
        if name != primary and iters is not None and assembly is not None:
            fs = row.get("factor_solve", {}).get(DIRECT_FOR.get(name, ""), {}).get("seconds")
            if fs is not None:
                pred = iters * (fs + assembly["residual_and_tangent_s"] + assembly["residual_s"])
        if pred is not None and pred > args.budget:
            skipped[name] = f"predicted {pred:.0f} s per solve > {args.budget:.0f} s"
            log(f"{label} {n} dofs: jaxfem {name} skipped ({skipped[name]})")
            continue
        if name == "dense" and n > 12_000:
            skipped[name] = "dense LU needs n^2 memory; run at the smallest size only"
            continue
        t0 = time.perf_counter()
        solver = jf.Solver(pb, linear_solver=name)
        setup = time.perf_counter() - t0
        try:
            r, sol = run_jaxfem(solver, theta, args.repeats, budget=args.budget)
        except jf.SolverError as e:
            skipped[name] = f"SolverError: {e}"[:300]
            continue
        r["setup_s"] = setup
        jax_rows[name] = r
        log(f"{label} {n} dofs: jaxfem {name:24s} warm {r['warm_s']:.3f} s, compile {r['compile_s']:.1f} s, "
            f"{r['iterations']} its / {r['steps']} steps, {r['per_iteration_s']:.4f} s/it")
        ext.add(("jaxfem", name), n, r["warm_s"])
        if name == primary:
            iters = r["iterations"]
            row["newton_log"] = sol.newton_log()
            row["nnz"] = solver.pattern.nnz
            row["auto_resolves_to"] = auto_choice(n, pb.mesh.dim)
            row["reaction_x"] = float(solver.reactions(sol.u, theta, right)[0])
            assembly, vals = assembly_times(solver, sol.u, theta)
            row["assembly"] = assembly
            log(f"{label} {n} dofs: assembly R+K {assembly['residual_and_tangent_s']:.4f} s, "
                f"R {assembly['residual_s']:.4f} s, min det F {assembly['min_jacobian_s']:.4f} s")
            # 2. one factor + solve of that tangent by every direct solver
            pat = solver.pattern
            b = np.random.default_rng(0).standard_normal(n)
            skip = {d: ext.predict(("direct", d), n) for d in _peers.available_direct()}
            fs = _peers.direct_solvers(pat.indptr, pat.cols, pat.rows, vals, b, repeats=args.repeats,
                                       skip=skip, budget=args.budget / max(iters, 1) * 2)
            for d, r in fs.items():
                if "seconds" in r:
                    ext.add(("direct", d), n, r["seconds"])
                log(f"{label} {n} dofs: factor+solve {d:15s} " +
                    (f"{r['seconds']:.4f} s (rel. residual {r['rel_residual']:.1e})" if "seconds" in r
                     else str(r)))
            row["factor_solve"] = fs
            # analysis vs factorisation (what reusing the symbolic analysis would save)
            split = {}
            for d in ("pardiso", "cholmod"):
                key = "pardiso_jaxfem" if d == "pardiso" else "cholmod"
                if "seconds" in fs.get(key, {}):
                    try:
                        split[d] = _peers.phase_split(d, pat.indptr, pat.cols, vals, b)
                    except Exception as e:  # noqa: BLE001
                        split[d] = {"error": str(e)[:200]}
            row["phase_split"] = split
            # CSR -> CSC conversion that jaxfem's superlu does (the matrix is symmetric: not needed)
            import scipy.sparse as sps
            A = sps.csr_matrix((vals, pat.cols, pat.indptr), shape=(n, n))
            row["csr_to_csc_s"], _, _ = best_of(lambda: A.tocsc(), 3)
        del solver, sol
        gc.collect()
    row["jaxfem"] = jax_rows
    row["jaxfem_skipped"] = skipped
    summarize_row(row)
    return row, sols


def summarize_row(row):
    jr = {k: v for k, v in row.get("jaxfem", {}).items() if "warm_s" in v}
    fs = {k: v for k, v in row.get("factor_solve", {}).items() if "seconds" in v}
    if jr:
        best = min(jr, key=lambda k: jr[k]["warm_s"])
        row["fastest_jaxfem"] = best
        row["fastest_jaxfem_warm_s"] = jr[best]["warm_s"]
        bp = min(jr, key=lambda k: jr[k]["per_iteration_s"])
        row["best_per_iteration_s"] = jr[bp]["per_iteration_s"]
        row["best_per_iteration_solver"] = bp
    if fs:
        f = min(fs, key=lambda k: fs[k]["seconds"])
        row["fastest_factor_solve"] = f
        row["fastest_factor_solve_s"] = fs[f]["seconds"]
    if jr and fs:
        row["per_iteration_over_fastest_factor_solve"] = row["best_per_iteration_s"] / row["fastest_factor_solve_s"]
        numeric = {d: v["factor"] + v["solve"] for d, v in row.get("phase_split", {}).items() if "factor" in v}
        row["per_iteration_ratio"] = {
            "ratio": row["per_iteration_over_fastest_factor_solve"],
            "numerator": {"what": "best jaxfem seconds per Newton iteration at this size: min over jaxfem's linear "
                                  "solvers of warm solve seconds / linear solves (predictors and abandoned, cut-back "
                                  "attempts included); an iteration = residual + tangent assembly, one linear solve, "
                                  "the inverted-element guard and the residual after the update",
                          "solver": row["best_per_iteration_solver"], "seconds": row["best_per_iteration_s"]},
            "denominator": {"what": "fastest one complete factor + solve of the same matrix (jaxfem's constrained "
                                    "tangent at the solution) among all direct solvers in factor_solve: from the CSR "
                                    "values to x, ordering/symbolic analysis included, best of N, fresh solver object",
                            "solver": row["fastest_factor_solve"], "seconds": row["fastest_factor_solve_s"],
                            "candidates": {k: v["seconds"] for k, v in fs.items()}},
            "target": "ratio <= 1.5",
            "for_reference_numeric_only": None if not numeric else {
                "what": "the same numerator over the fastest numeric factorisation + solve alone (symbolic analysis "
                        "excluded, from phase_split), which is what an iteration that reuses the analysis must pay",
                "solver": min(numeric, key=numeric.get), "seconds": min(numeric.values()),
                "ratio": row["best_per_iteration_s"] / min(numeric.values())}}
        a = row.get("assembly", {})
        if a:
            it = row["best_per_iteration_s"]
            asm = a["residual_and_tangent_s"] + a["residual_s"] + 2 * a["min_jacobian_s"]
            lin_key = DIRECT_FOR.get(row["best_per_iteration_solver"].split("+")[0])
            lin = fs.get(lin_key, {}).get("seconds")
            row["iteration_split"] = {
                "solver": row["best_per_iteration_solver"], "per_iteration_s": it,
                "assembly_R_K_s": a["residual_and_tangent_s"], "residual_and_2_min_detF_s": asm - a["residual_and_tangent_s"],
                "factor_solve_s": lin,
                "assembly_fraction": asm / it,
                "factor_solve_fraction": None if lin is None else lin / it,
                "rest_s": None if lin is None else it - asm - lin}


# ====================================================================== sweeps
def sweep_sheet(args, mode):
    rows, rows_ps = RESULTS["sheet_plane_stress"], RESULTS["sheet_plane_strain"]
    ext, ext_sk = Extrapolator(1.5), Extrapolator(1.3)
    for k, (nx, ny) in enumerate(SIZES_2D[mode]):
        old = reused("sheet_plane_stress", args, 2 * (nx + 1) * (ny + 1), nx=nx, ny=ny)
        old_ps = reused("sheet_plane_strain", args, 2 * (nx + 1) * (ny + 1), nx=nx, ny=ny)
        if old is not None and old_ps is not None:
            rows.append(old)
            rows_ps.append(old_ps)
            seed(ext, old)
            if "seconds" in old_ps.get("skfem", {}):
                ext_sk.add("skfem", old_ps["dofs"], old_ps["skfem"]["seconds"])
            log(f"sheet {old['dofs']} dofs: reused from {args.reuse}")
            continue
        if not args.min_dofs <= 2 * (nx + 1) * (ny + 1) <= args.max_dofs:
            continue
        pb, theta, right = sheet(nx, ny)
        extra = ("cg", "dense") if k == 0 else ()
        row, sols = measure_size(pb, theta, right, args, ext, "sheet", extra)
        row.update(nx=nx, ny=ny)
        rows.append(row)
        del sols
        gc.collect()
        # plane strain: jaxfem (SuperLU, and the fastest plane-stress solver) against scikit-fem
        pbs, ths, rights = sheet(nx, ny, "plane-strain")
        ps = {"dofs": pbs.n_dofs, "nx": nx, "ny": ny, "jaxfem": {}}
        names = ["superlu"]
        fastest = row.get("fastest_jaxfem", "superlu").split("+")[0]
        if fastest not in names and fastest in ("pardiso", "klu"):
            names.append(fastest)
        u_ref, steps = None, 1
        for name in names:
            pred = ext.predict(("jaxfem", name), pbs.n_dofs)
            if pred is not None and pred > args.budget:
                ps["jaxfem"][name] = {"skipped": f"predicted {pred:.0f} s > {args.budget:.0f} s"}
                continue
            solver = jf.Solver(pbs, linear_solver=name)
            r, sol = run_jaxfem(solver, ths, args.repeats, budget=args.budget)
            ps["jaxfem"][name] = r
            u_ref, steps = np.asarray(sol.u), r["steps"]
            ps["reaction_x"] = float(solver.reactions(sol.u, ths, rights)[0])
            log(f"plane strain {pbs.n_dofs} dofs: jaxfem {name} warm {r['warm_s']:.3f} s "
                f"({r['iterations']} its, compile {r['compile_s']:.1f} s)")
        pred = ext_sk.predict("skfem", pbs.n_dofs)
        if pred is not None and pred > args.peer_budget:
            ps["skfem"] = {"skipped": f"predicted {pred:.0f} s > {args.peer_budget:.0f} s"}
        else:
            try:
                sk = _peers.skfem_plane_strain(pbs.mesh.nodes, pbs.mesh.cells, pbs.fixed, np.asarray(ths["u_D"]),
                                               E_SHEET, NU, n_steps=steps, repeats=args.repeats,
                                               budget=args.peer_budget)
                u_sk = sk.pop("u")
                if u_ref is not None:
                    sk["max_abs_diff_u_vs_jaxfem"] = float(np.abs(u_sk - u_ref).max())
                    sk["max_abs_u"] = float(np.abs(u_ref).max())
                ext_sk.add("skfem", pbs.n_dofs, sk["seconds"])
                ps["skfem"] = sk
                log(f"plane strain {pbs.n_dofs} dofs: scikit-fem {sk['seconds']:.3f} s ({sk['iterations']} its; "
                    f"solve {sk['linear_solve_seconds']:.2f} s, assembly {sk['assembly_seconds']:.2f} s), "
                    f"|u - u_jaxfem| {sk.get('max_abs_diff_u_vs_jaxfem', float('nan')):.1e}")
            except Exception as e:  # noqa: BLE001
                ps["skfem"] = {"error": f"{type(e).__name__}: {e}"[:300]}
        jr = {k: v for k, v in ps["jaxfem"].items() if "warm_s" in v}
        if jr and "seconds" in ps.get("skfem", {}):
            best = min(jr, key=lambda k: jr[k]["warm_s"])
            ps["fastest_jaxfem"] = best
            ps["skfem_over_jaxfem"] = ps["skfem"]["seconds"] / jr[best]["warm_s"]
            ps["skfem_over_jaxfem_superlu"] = (ps["skfem"]["seconds"] / jr["superlu"]["warm_s"]
                                               if "superlu" in jr else None)
        rows_ps.append(ps)
        write_partial(args)


def sweep_block(args, mode):
    rows = RESULTS["block"]
    ext, ext_tf = Extrapolator(2.0), Extrapolator(1.5)
    for n in SIZES_3D[mode]:
        old = reused("block", args, 3 * (2 * n + 1) * (n + 1) ** 2, n=n)
        if old is not None:
            rows.append(old)
            seed(ext, old)
            for k, v in old.get("torchfem", {}).items():
                if "seconds" in v:
                    ext_tf.add(("torchfem", int(k.split("_")[1])), old["dofs"], v["seconds"])
            log(f"block {old['dofs']} dofs: reused from {args.reuse}")
            continue
        if not args.min_dofs <= 3 * (2 * n + 1) * (n + 1) ** 2 <= args.max_dofs:
            continue
        pb, theta, right = block(n)
        row, sols = measure_size(pb, theta, right, args, ext, "block")
        row.update(n=n, mesh=f"{2 * n} x {n} x {n} hex8")
        del sols
        gc.collect()
        # torch-fem on the same mesh and boundary conditions, the full stretch in one increment
        cons = np.zeros((pb.mesh.n_nodes, 3), bool)
        cons.reshape(-1)[pb.fixed] = True
        rmask = np.zeros(pb.mesh.n_nodes, bool)
        rmask[right] = True
        job = {"kind": "block", "E": E_SHEET, "nu": NU, "nodes": pb.mesh.nodes, "cells": pb.mesh.cells,
               "constraints": cons, "u_D": np.asarray(theta["u_D"]), "right": rmask,
               "increments": np.array([0.0, 1.0]), "repeats": args.repeats, "budget": args.peer_budget}
        tfr = {}
        for threads in (args.torchfem_threads if n == SIZES_3D[mode][0] else (1,)):
            pred = ext_tf.predict(("torchfem", threads), pb.n_dofs)
            if pred is not None and pred > args.peer_budget:
                tfr[f"threads_{threads}"] = {"skipped": f"predicted {pred:.0f} s > {args.peer_budget:.0f} s"}
                continue
            r = _peers.torchfem_run(dict(job, repeats=job["repeats"] if threads == 1 else 1),
                                    timeout=4 * args.peer_budget + 60, threads=threads)
            tfr[f"threads_{threads}"] = r
            if "seconds" in r:
                ext_tf.add(("torchfem", threads), pb.n_dofs, r["seconds"])
                log(f"block {pb.n_dofs} dofs: torch-fem ({threads} thread) {r['seconds']:.2f} s, "
                    f"{r['iterations']} its, {r['method']}/{r['library']}, reaction {r['reaction_x']:.6g} "
                    f"(jaxfem {row.get('reaction_x', float('nan')):.6g})")
            else:
                log(f"block {pb.n_dofs} dofs: torch-fem ({threads} thread): {r}")
        row["torchfem"] = tfr
        ok = [v["seconds"] for v in tfr.values() if "seconds" in v]
        if ok and "fastest_jaxfem_warm_s" in row:
            row["torchfem_over_jaxfem"] = min(ok) / row["fastest_jaxfem_warm_s"]
        rows.append(row)
        write_partial(args)


def sweep_documented(args, mode):
    """torch-fem's own neo-Hookean benchmark (forward pass), and jaxfem on the same problem."""
    rows = RESULTS["torchfem_documented"]
    for N in DOC_N[mode]:
        old = reused("torchfem_documented", N=N)
        if old is not None:
            rows.append(old)
            log(f"torch-fem benchmark N={N}: reused from {args.reuse}")
            continue
        pb, theta, right = torchfem_cube(N)
        row = {"N": N, "dofs": pb.n_dofs, "jaxfem": {}}
        solver = jf.Solver(pb)  # the default ("auto") linear solver
        r, sol = run_jaxfem(solver, theta, args.repeats, budget=args.budget)
        row["jaxfem"][f"{solver.linear_solver} (auto; own load stepping)"] = r
        row["jaxfem_reaction_x"] = float(solver.reactions(sol.u, theta, right)[0])
        log(f"torch-fem benchmark N={N} ({pb.n_dofs} dofs): jaxfem {r['warm_s']:.3f} s, {r['iterations']} its, "
            f"{r['steps']} steps, {r['cutbacks']} cutbacks, compile {r['compile_s']:.1f} s")
        # the same 20 geometric increments as torch-fem, each solve continuing from the last
        lam = np.logspace(0, math.log10(1 + DOC["U"]), DOC["n_inc"])
        incs = (lam - 1) / DOC["U"]
        uD = np.asarray(theta["u_D"])

        def chained():
            u0, loads0, its = None, None, 0
            for s in incs[1:]:
                th = dict(theta, u_D=jnp.asarray(s * uD))
                sl = solver.solve(th, start=None if u0 is None else (u0, loads0))
                u0 = sl.u
                loads0 = {k: th[k] for k in ("u_D", "f", "traction")}
                its += int(sl.info["iterations"])
            jax.block_until_ready(u0)
            return its
        chained()
        t, times, its = best_of(chained, args.repeats, budget=args.budget)
        row["jaxfem"][f"{solver.linear_solver} (torch-fem's 20 increments)"] = {"warm_s": t, "all_warm_s": times, "iterations": its,
                                                               "steps": len(incs) - 1, "load": loadavg()}
        log(f"torch-fem benchmark N={N}: jaxfem with torch-fem's increments {t:.3f} s, {its} its")
        tfr = {}
        for threads in (args.torchfem_threads if N == DOC_N[mode][0] else (1,)):
            job = {"kind": "documented", "N": N, "U": DOC["U"], "n_inc": DOC["n_inc"], "E": DOC["E"],
                   "nu": DOC["nu"], "repeats": 1 if N > 5 or threads > 1 else args.repeats,
                   "budget": args.peer_budget}
            r = _peers.torchfem_run(job, timeout=6 * args.peer_budget + 120, threads=threads)
            tfr[f"threads_{threads}"] = r
            log(f"torch-fem benchmark N={N}: torch-fem ({threads} thread) " +
                (f"{r['seconds']:.2f} s, {r['iterations']} its, reaction {r['reaction_x']:.8g} "
                 f"(jaxfem {row['jaxfem_reaction_x']:.8g})" if "seconds" in r else str(r)))
        row["torchfem"] = tfr
        ok = [v["seconds"] for v in tfr.values() if "seconds" in v]
        if ok:
            row["torchfem_s"] = min(ok)
            best_j = min(v["warm_s"] for v in row["jaxfem"].values())
            row["torchfem_over_jaxfem"] = min(ok) / best_j
        rows.append(row)
        write_partial(args)


# ====================================================================== output (verdict and plot: _forward_report.py)
def versions():
    out = {}
    for pkg in ("jax", "jaxlib", "numpy", "scipy", "scikit-fem", "klujax", "pypardiso", "mkl", "scikit-sparse",
                "torch", "torch-fem", "pyamg"):
        try:
            out[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            out[pkg] = None
    return out


RESULTS: dict = {}
REUSE: dict = {}


def reused(kind, args=None, dofs=None, **key):
    """The row of an earlier run (--reuse) with the same size, or None (also with --remeasure for
    a size within --min-dofs .. --max-dofs)."""
    if args is not None and args.remeasure and args.min_dofs <= dofs <= args.max_dofs:
        return None
    for r in REUSE.get(kind, []):
        if all(r.get(k) == v for k, v in key.items()):
            return r
    return None


def seed(ext, row):
    """Feed a reused row's timings to the extrapolator (for the skip predictions)."""
    for name, r in row.get("jaxfem", {}).items():
        if "warm_s" in r and "+" not in name:
            ext.add(("jaxfem", name), row["dofs"], r["warm_s"])
    for name, r in row.get("factor_solve", {}).items():
        if "seconds" in r:
            ext.add(("direct", name), row["dofs"], r["seconds"])


def write_partial(args):
    RESULTS["meta"]["load_now"] = loadavg()
    flag_load(RESULTS)
    RESULTS["targets"] = targets(RESULTS)
    Path(args.out).write_text(json.dumps(RESULTS, indent=1, default=_json_default))
    try:
        plot(RESULTS, Path(args.out).with_suffix(".png"))
    except Exception as e:  # noqa: BLE001 - a plot must not end a long run
        log(f"plot failed: {e}")


def memory_watchdog(limit_gb):
    """Abort (with every thread's stack) if this process's resident memory passes ``limit_gb``: the
    machine may be shared, and a sparse factorisation with bad fill can take it all."""
    import faulthandler
    import threading

    def rss_gb():
        return int(open("/proc/self/statm").read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 1e9

    def watch():
        while True:
            if rss_gb() > limit_gb:
                log(f"resident memory {rss_gb():.1f} GB > {limit_gb:.1f} GB: aborting")
                faulthandler.dump_traceback(all_threads=True)
                os._exit(3)
            time.sleep(0.25)

    threading.Thread(target=watch, daemon=True).start()


def mem_available_gb():
    for line in open("/proc/meminfo"):
        if line.startswith("MemAvailable:"):
            return int(line.split()[1]) / 1e6
    return 8.0


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--full", action="store_true", help="add the large sizes (2D to 406k, 3D to 103k DOFs)")
    ap.add_argument("--quick", action="store_true", help="tiny sizes, one repeat: a smoke test")
    ap.add_argument("--budget", type=float, default=60.0, help="skip a jaxfem solve predicted over this (s)")
    ap.add_argument("--peer-budget", type=float, default=None, help="same for one peer solve (s)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--solvers", default=None, help="comma-separated jaxfem linear solvers to run (default: all)")
    ap.add_argument("--torchfem-threads", default="1,2",
                    help="thread counts for torch-fem at the smallest size (larger sizes: 1); on a loaded "
                         "machine a 2-thread run mostly measures the contention")
    ap.add_argument("--only", choices=["sheet", "block", "documented"], action="append")
    ap.add_argument("--out", default=str(HERE / "results" / "forward.json"))
    ap.add_argument("--max-dofs", type=int, default=10**9, help="leave out the sheet and block sizes above this")
    ap.add_argument("--min-dofs", type=int, default=0, help="... and below this (unless --reuse has them)")
    ap.add_argument("--max-memory-gb", type=float, default=None,
                    help="abort past this resident memory (default: 75 %% of what is available at the start)")
    ap.add_argument("--reuse", default=None, help="an earlier forward.json: keep its rows of the same sizes "
                    "and measure only the others (e.g. --full after a default run)")
    ap.add_argument("--remeasure", action="store_true", help="with --reuse: measure the sizes within "
                    "--min-dofs .. --max-dofs again, keep the reused rows of the others")
    args = ap.parse_args()
    args.torchfem_threads = tuple(int(t) for t in args.torchfem_threads.split(","))
    args.solvers = args.solvers.split(",") if args.solvers else None
    if args.reuse:
        REUSE.update(json.loads(Path(args.reuse).read_text()))
    memory_watchdog(args.max_memory_gb or min(0.75 * mem_available_gb(), 12.0))
    mode = "quick" if args.quick else "full" if args.full else "default"
    if args.quick:
        args.repeats = 1
    if args.peer_budget is None:
        args.peer_budget = 180.0 if args.full else 60.0
    png = Path(args.out).with_suffix(".png")
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    t_start = time.time()
    os.environ.pop("PYPARDISO_MKL_RT", None)
    pinit = _peers.pardiso_construction_seconds() if "pardiso" in available() else None
    args.pardiso_init_s = pinit["seconds_without_PYPARDISO_MKL_RT"] if pinit else 0.0
    RESULTS.clear()
    RESULTS["meta"] = {
        "mode": mode, "date": time.strftime("%Y-%m-%d %H:%M:%S"), "cpu": f"{os.cpu_count()} cores, {platform.machine()}",
        "platform": platform.platform(), "python": platform.python_version(), "versions": versions(),
        "jax_devices": [str(d) for d in jax.devices()], "load_start": loadavg(),
        "budget_s": args.budget, "peer_budget_s": args.peer_budget, "repeats": args.repeats,
        "command_line": sys.argv[1:], "torchfem_threads": list(args.torchfem_threads),
        "reused_rows_from": None if not args.reuse else {"file": args.reuse, "date": REUSE.get("meta", {}).get("date"),
                                                          "load_start": REUSE.get("meta", {}).get("load_start"),
                                                          "command_line": REUSE.get("meta", {}).get("command_line"),
                                                          "reused_rows_from": REUSE.get("meta", {}).get("reused_rows_from")},
        "auto_klu_max_dofs_2d_without_pardiso": AUTO_KLU_MAX_DOFS_2D, "linear_solvers_available": available(),
        "direct_solvers_available": _peers.available_direct(),
        "problems": {
            "sheet": f"{SHEET[0]:g} x {SHEET[1]:g} rectangle, tri3 (square cells split in two), neo-Hookean "
                     f"E={E_SHEET}, nu={NU}, plane stress; left edge u_x = 0, right edge u_x = {STRETCH} L, "
                     "u_y = 0 at the bottom-left node",
            "block": f"{BLOCK[0]:g} x {BLOCK[1]:g} x {BLOCK[2]:g} block, hex8 (2n x n x n cubes), same law; left face "
                     f"u_x = 0, right face u_x = {STRETCH} L, u_y = u_z = 0 at (0,0,0), u_z = 0 at (0,L_y,0)",
            "torchfem_documented": "torch-fem benchmarks/hyperelasticity.py: unit cube, (N-1)^3 hex8, E=1000, nu=0.3, "
                                   "right face stretched to 20x the length (u_x = 19) in 20 geometric increments, "
                                   "symmetry planes y = z = 0.5; forward pass timed (parameters declared differentiable, as there)",
        },
        "timing": "warm = best of N (3, fewer where they would pass the budget) calls after the first; compile = first - warm; iterations = linear solves incl. "
                  "the predictor (failed, cut-back attempts included); factor+solve = one solve of the constrained "
                  "tangent at the solution, from the CSR values to x, best of N; each timing carries the 1-min "
                  "load average when it was taken (the machine may be shared)",
    }
    RESULTS["pardiso_construction"] = pinit
    RESULTS["install"] = {
        "scikit-sparse": "plain `pip install scikit-sparse` fails here (0.5.0 builds from source: no cholmod.h; "
                         "with Debian's libsuitesparse-dev 5.12 its C code needs SuiteSparse 7). Works: "
                         "`apt-get install libsuitesparse-dev && pip install scikit-sparse==0.4.16` (~45 s).",
        "torch-fem": "`pip install torch==2.13.0` (local CPU wheel), `pip install torch-fem --no-deps pyamg`; "
                     "pyvista (VTK, plotting only) is stubbed out in the child process.",
    }
    only = set(args.only or ["sheet", "block", "documented"])
    for part, kinds in (("sheet", ("sheet_plane_stress", "sheet_plane_strain")), ("block", ("block",)),
                        ("documented", ("torchfem_documented",))):
        if part not in only:  # parts not measured now: carried over from --reuse
            for k in kinds:
                if k in REUSE:
                    RESULTS[k] = REUSE[k]
    if "sheet" in only:
        RESULTS["sheet_plane_stress"], RESULTS["sheet_plane_strain"] = [], []
        sweep_sheet(args, mode)
    if "block" in only:
        RESULTS["block"] = []
        sweep_block(args, mode)
    if "documented" in only:
        RESULTS["torchfem_documented"] = []
        sweep_documented(args, mode)
    RESULTS["targets"] = targets(RESULTS)
    RESULTS["fastest_linear_solver_by_size"] = [
        {"problem": kind, "dofs": r["dofs"], "fastest_jaxfem": r.get("fastest_jaxfem"),
         "warm_s": {k: round(v["warm_s"], 4) for k, v in r["jaxfem"].items() if "warm_s" in v},
         "fastest_factor_solve": r.get("fastest_factor_solve")}
        for kind in ("sheet_plane_stress", "block") for r in RESULTS.get(kind, [])]
    RESULTS["meta"]["wall_seconds"] = time.time() - t_start
    write_partial(args)
    plot(RESULTS, png)
    log(f"wrote {args.out} and {png} in {RESULTS['meta']['wall_seconds']:.0f} s")
    print(json.dumps(RESULTS["targets"], indent=1, default=_json_default))


if __name__ == "__main__":
    main()
