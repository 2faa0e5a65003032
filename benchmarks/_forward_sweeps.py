"""The sweeps of benchmarks/forward.py over mesh sizes (sheet with its plane-strain scikit-fem peer,
block with torch-fem, torch-fem's own benchmark) and the results they fill, with --reuse of an
earlier run's rows and the partial writes after each size."""

from __future__ import annotations

import gc
import json
import math
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import jaxfem as jf

from benchmarks import _peers
from benchmarks._forward_measure import Extrapolator, log, measure_size, run_jaxfem
from benchmarks._forward_problems import DOC, DOC_N, E_SHEET, NU, SIZES_2D, SIZES_3D, block, sheet, torchfem_cube
from benchmarks._forward_report import _json_default, flag_load, plot, targets
from benchmarks._timing import best_of, loadavg

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

