"""Benchmark of jaxfem's derivatives: what a gradient costs next to the forward solve.

Two problems: a plane-stress neo-Hookean sheet (tri3, ~20k DOFs) stretched 20 %, and a 3D
neo-Hookean block (hex8, ~50k DOFs) stretched 10 %, both clamped at x = 0 and pulled at the far
end. The scalar is a measurement misfit 0.5 |u(probe points) - u_meas|^2; the parameters are the
per-element Young's moduli (one per cell, thousands). For each problem it measures, warm (after
compilation), best of 3:

- a forward solve (``jit(solver.displacement)``);
- ``jax.value_and_grad`` of the misfit with respect to the whole parameter pytree, and the
  gradient's overhead beyond the forward solve (the custom_jvp runs the primal solve inside);
- one JVP (``jax.jvp`` of theta -> u along a random E field), and its overhead;
- 8 solves with 8 different modulus fields, vmapped (``jaxfem.batch``), against lax.map and
  8 separate calls (in 3D: 8 x the forward solve, too slow to repeat);
- where the gradient's time goes: tangent assembly at u*, one factorisation + solve, and the
  VJP of the residual with respect to theta, each timed alone; and how many times the sparse
  direct solver runs in each call (counted on the host);
- Taylor rates of the misfit along a random E direction (reverse mode).

It compares the gradient overhead with the target "at most 0.5 x a forward solve" and with the
cost of finite differences (one forward solve per parameter, extrapolated). Compile times are
reported separately. Besides wall seconds it records the process's CPU seconds (all threads),
which other jobs on a shared machine disturb far less. Writes benchmarks/results/gradients.json
(one entry per problem, and ``targets`` with pass/fail) and gradients.png.

    python -m benchmarks gradients                    # ~15 CPU minutes (55 wall minutes at load 10)
    python -m benchmarks gradients --only block-3d    # one problem; updates its entry in the json
    python -m benchmarks gradients --quick            # small meshes, a smoke test
    python -m benchmarks gradients --plot             # redraw gradients.png from the json
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402

import jaxfem as jf  # noqa: E402
from jaxfem import linsolve  # noqa: E402
from jaxfem.batch import batch_displacement  # noqa: E402
from benchmarks._cli import QUICK  # noqa: E402

TARGET_OVERHEAD = 0.5  # gradient beyond the forward solve, in forward solves
BATCH = 8
REPEATS = 3

# ---------------------------------------------------------------- counting sparse factorisations
FACTORISATIONS = {"n": 0}


def _install_counters():
    """Count the host-side factorisations of SuperLU and PARDISO (numeric factorisations of
    :class:`jaxfem.linsolve.PardisoHandle`, whose symbolic analysis runs once per pattern)."""
    splu = linsolve.superlu.spla.splu

    def counted_splu(*a, **kw):
        FACTORISATIONS["n"] += 1
        return splu(*a, **kw)

    linsolve.superlu.spla.splu = counted_splu
    factor = linsolve.PardisoHandle.factor

    def counted_factor(self, a):
        FACTORISATIONS["n"] += 1
        return factor(self, a)

    linsolve.PardisoHandle.factor = counted_factor


# ---------------------------------------------------------------- problems
def sheet(quick: bool):
    """Plane-stress sheet 140 x 80, tri3, ~20k DOFs, 20 % stretch."""
    nx, ny = (40, 22) if quick else (132, 75)
    mesh = jf.rectangle(0, 0, 140, 80, nx, ny)
    fixed = np.concatenate([jf.dofs(mesh, mesh.side("left")), jf.dofs(mesh, mesh.side("right"))])
    problem = jf.Problem(mesh, "neo-hookean", "plane-stress", fixed=fixed)
    u_D = problem.prescribe(lambda X: 0.2 * X * [1.0, 0.0])
    grid = np.stack(np.meshgrid(np.linspace(20, 120, 21), np.linspace(10, 70, 13)), -1).reshape(-1, 2)
    return "sheet-2d", mesh, problem, u_D, grid


def block(quick: bool):
    """3D block 40 x 20 x 16, hex8, ~50k DOFs, 10 % stretch."""
    n = (12, 6, 5) if quick else (43, 21, 17)
    mesh = jf.box(0, 0, 0, 40, 20, 16, *n, "hex8")
    fixed = np.concatenate([jf.dofs(mesh, mesh.side("left")), jf.dofs(mesh, mesh.side("right"))])
    problem = jf.Problem(mesh, "neo-hookean", fixed=fixed)
    u_D = problem.prescribe(lambda X: 0.1 * X * [1.0, 0.0, 0.0])
    g = [np.linspace(4, 36, 9), np.linspace(3, 17, 5), np.linspace(3, 13, 4)]
    grid = np.stack(np.meshgrid(*g), -1).reshape(-1, 3)
    return "block-3d", mesh, problem, u_D, grid


# ---------------------------------------------------------------- timing
def compiled(jitted, *args):
    """(the compiled ``jitted`` for ``args``, compile seconds: tracing, lowering and XLA)."""
    t0 = time.perf_counter()
    exe = jitted.lower(*args).compile()
    return exe, time.perf_counter() - t0


CPU_SECONDS = {}  # name -> best process CPU seconds (all threads), robust to other jobs' load


def best_of(fn, *args, repeats=REPEATS, name=None):
    """(best warm wall seconds, factorisations per call) of ``fn(*args)``, after one untimed call
    (``repeats=0``: the untimed call is the measurement, for runs too long to repeat)."""
    wall, cpu = [], []
    for k in range(repeats + 1):
        FACTORISATIONS["n"] = 0
        t0, c0 = time.perf_counter(), time.process_time()
        jax.block_until_ready(fn(*args))
        if k or not repeats:
            wall.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
    if name:
        CPU_SECONDS[name] = min(cpu)
    return min(wall), FACTORISATIONS["n"]


def taylor_rates(value_and_grad, theta, direction):
    """Reverse-mode Taylor rates, reusing the compiled value_and_grad for every value."""
    f = jax.custom_vjp(lambda th: value_and_grad(th)[0])
    f.defvjp(value_and_grad, lambda g, ct: (jax.tree.map(lambda a: ct * a, g),))
    return jf.taylor_test(f, theta, direction, h0=1e-2, steps=4, mode="reverse").rates1.tolist()


def run(build, quick: bool, separate_batch: bool) -> dict:
    name, mesh, problem, u_D, points = build(quick)
    solver = jf.Solver(problem)
    print(f"{name}: {problem.n_dofs} DOFs, {mesh.n_cells} cells, linear solver {solver.linear_solver}", flush=True)
    rng = np.random.default_rng(0)
    theta = problem.params(E=83.76, nu=0.3, u_D=u_D)
    probe = jf.locate(mesh, points)
    forward = jax.jit(solver.displacement)
    fwd, c_fwd = compiled(forward, theta)
    stiff = theta["E"] * np.exp(0.3 * rng.normal(size=mesh.n_cells))  # a "true" modulus field
    measured = probe(fwd({**theta, "E": stiff})) + 0.01 * rng.normal(size=(len(points), mesh.dim))

    def misfit(th):
        return 0.5 * jnp.sum((probe(solver.displacement(th)) - measured) ** 2)

    value_and_grad = jax.jit(jax.value_and_grad(misfit))
    dE = jnp.asarray(0.1 * theta["E"] * rng.normal(size=mesh.n_cells))
    direction = {**jax.tree.map(jnp.zeros_like, theta), "E": dE}
    jvp = jax.jit(lambda th, d: jax.jvp(solver.displacement, (th,), (d,)))
    moduli = theta["E"] * rng.uniform(0.7, 1.3, size=(BATCH, 1))
    batched = {**theta, "E": jnp.asarray(moduli)}
    vmapped = batch_displacement(solver, batched=["E"], method="vmap")
    mapped = batch_displacement(solver, batched=["E"], method="map")

    out = {"dofs": problem.n_dofs, "cells": mesh.n_cells, "n_params_E": mesh.n_cells,
           "n_params_total": int(sum(np.size(v) for v in theta.values())),
           "linear_solver": solver.linear_solver, "probe_points": len(points)}
    info = solver.solve(theta).info
    out["newton"] = {"load_steps": int(info["steps"]), "iterations": int(info["iterations"])}
    vg, c_vg = compiled(value_and_grad, theta)
    tan, c_jvp = compiled(jvp, theta, direction)
    vm, c_vmap = compiled(vmapped, batched)
    CPU_SECONDS.clear()
    t_fwd, n_fwd = best_of(fwd, theta, name="forward")
    t_vg, n_vg = best_of(vg, theta, name="value_and_grad")
    t_jvp, n_jvp = best_of(tan, theta, direction, name="jvp")
    t_vmap, n_vmap = best_of(vm, batched, repeats=0, name=f"batch{BATCH}_vmap")
    seconds = {"forward": t_fwd, "value_and_grad": t_vg, "gradient_overhead": t_vg - t_fwd,
               "jvp": t_jvp, "jvp_overhead": t_jvp - t_fwd, f"batch{BATCH}_vmap": t_vmap}
    compile_seconds = {"forward": c_fwd, "value_and_grad": c_vg, "jvp": c_jvp, f"batch{BATCH}_vmap": c_vmap}
    if separate_batch:
        mp, compile_seconds[f"batch{BATCH}_lax_map"] = compiled(mapped, batched)
        seconds[f"batch{BATCH}_lax_map"] = best_of(mp, batched, repeats=0, name=f"batch{BATCH}_lax_map")[0]
        seconds[f"batch{BATCH}_separate"] = sum(best_of(fwd, {**theta, "E": jnp.asarray(m)}, repeats=0)[0]
                                                for m in moduli)
    else:  # too slow to repeat: 8 separate solves extrapolated from the best forward solve
        seconds[f"batch{BATCH}_separate_extrapolated"] = BATCH * t_fwd
    out["seconds"], out["compile_seconds"] = seconds, compile_seconds
    out["cpu_seconds"] = dict(CPU_SECONDS)
    out["cpu_gradient_overhead_in_forward_solves"] = (CPU_SECONDS["value_and_grad"] / CPU_SECONDS["forward"]) - 1
    out["factorisations_per_call"] = {"forward": n_fwd, "value_and_grad": n_vg, "jvp": n_jvp,
                                      f"batch{BATCH}_vmap": n_vmap}
    out["gradient_overhead_in_forward_solves"] = (t_vg - t_fwd) / t_fwd
    out["meets_target"] = out["gradient_overhead_in_forward_solves"] <= TARGET_OVERHEAD
    out["finite_differences"] = {"forward_solves": mesh.n_cells, "seconds_extrapolated": mesh.n_cells * t_fwd,
                                 "speedup_of_adjoint": mesh.n_cells * t_fwd / t_vg}
    out["breakdown"] = breakdown(solver, theta, fwd(theta))
    out["taylor_rates_E_reverse"] = taylor_rates(vg, theta, direction)
    print(json.dumps(out, indent=1), flush=True)
    return out


def breakdown(solver, theta, u) -> dict:
    """Warm wall and CPU seconds of the pieces of the gradient beyond the forward solve, each
    jitted alone: the tangent at u*, one factorisation + solve, the VJP of the residual with
    respect to theta (what the adjoint needs), and a residual evaluation for scale."""
    u = jnp.asarray(u).reshape(-1)
    arrays = solver.arrays
    tangent = jax.jit(lambda uu, th: solver._constrained(solver.tangent_values(uu, th)))
    M = tangent(u, theta)
    rhs = jnp.asarray(np.random.default_rng(3).normal(size=u.shape))
    solve = jax.jit(lambda m, b, s: solver._lin(m * s, b, arrays))
    scales = iter(1.0 + 1e-3 * np.arange(1, 100))  # a new matrix every call: no cached factorisation
    pieces = {"tangent_assembly": (tangent, u, theta),
              "factorise_and_solve": (lambda m, b: solve(m, b, next(scales)), M, rhs),
              "residual_vjp_theta": (jax.jit(lambda uu, th, w: jax.vjp(lambda t: solver.residual(uu, t), th)[1](w)),
                                     u, theta, rhs),
              "residual": (jax.jit(solver.residual), u, theta)}
    CPU_SECONDS.clear()
    wall = {k: best_of(fn, *args, name=k)[0] for k, (fn, *args) in pieces.items()}
    return {"wall": wall, "cpu": dict(CPU_SECONDS)}


def problems(results: dict) -> dict:
    """The per-problem entries of the results (every key but ``targets``)."""
    return {name: r for name, r in results.items() if name != "targets"}


def targets(results: dict) -> dict:
    """Pass or fail of the target, computed from the problems measured: the gradient
    (``value_and_grad``) costs at most TARGET_OVERHEAD forward solves beyond the forward solve, in
    warm wall seconds (the CPU-seconds ratio is given for reference)."""
    rows = [{"problem": name, "dofs": r["dofs"], "n_params_E": r["n_params_E"],
             "overhead_in_forward_solves": r["gradient_overhead_in_forward_solves"],
             "cpu_overhead_in_forward_solves": r["cpu_gradient_overhead_in_forward_solves"],
             "pass": bool(r["gradient_overhead_in_forward_solves"] <= TARGET_OVERHEAD)}
            for name, r in problems(results).items()]
    return {f"gradient_overhead_at_most_{TARGET_OVERHEAD:g}_forward_solves": {
        "threshold": TARGET_OVERHEAD, "rows": rows, "pass": bool(rows) and all(r["pass"] for r in rows)}}


def plot(results: dict, path: Path):
    """Bars of wall and CPU seconds per problem, with the 0.5 x forward target for the overhead."""
    results = problems(results)
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(results), figsize=(6 * len(results), 4.2), squeeze=False)
    for ax, (name, r) in zip(axes[0], results.items()):
        labels = ["forward", "value\n+grad", "grad\noverhead", "JVP", f"vmap {BATCH}\n/ {BATCH}"]
        x = np.arange(len(labels))
        for k, (kind, s) in enumerate((("wall", r["seconds"]), ("CPU", r["cpu_seconds"]))):
            overhead = s["value_and_grad"] - s["forward"]
            vals = [s["forward"], s["value_and_grad"], overhead, s["jvp"], s[f"batch{BATCH}_vmap"] / BATCH]
            ax.bar(x + (k - 0.5) * 0.38, vals, 0.38, label=f"{kind} seconds")
            ax.hlines(TARGET_OVERHEAD * s["forward"], 1.6, 2.4, colors=f"C{k}", linestyles="--", lw=1.5)
        ax.set_xticks(x, labels)
        load = r.get("machine", {}).get("load_average_at_start", [np.nan])[0]
        ax.set_title(f"{name}: {r['dofs']} DOFs, {r['n_params_E']} moduli ({r['linear_solver']})\n"
                     f"dashes: target overhead 0.5 x forward; load average {load:.0f} on {r['machine']['cpus']} cores",
                     fontsize=9)
        ax.set_ylabel("warm seconds, best of 3")
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="small meshes (smoke test)")
    parser.add_argument("--only", choices=["sheet-2d", "block-3d"], help="run one problem")
    parser.add_argument("--plot", action="store_true", help="only redraw the plot from the saved results")
    args = parser.parse_args(argv)
    _install_counters()
    builds = {"sheet-2d": (sheet, True), "block-3d": (block, args.quick)}
    out = QUICK if args.quick else ROOT / "benchmarks" / "results"
    out.mkdir(parents=True, exist_ok=True)
    path = out / "gradients.json"
    results = json.loads(path.read_text()) if (args.only or args.plot) and path.exists() else {}
    if args.plot:
        return plot(results, path.with_suffix(".png"))
    for key, (build, separate_batch) in builds.items():
        if args.only in (None, key):
            machine = {"cpus": os.cpu_count(), "load_average_at_start": os.getloadavg(), "jax": jax.__version__}
            results[key] = {"machine": machine, **run(build, args.quick, separate_batch)}
            results[key]["machine"]["load_average_at_end"] = os.getloadavg()
    results["targets"] = targets(results)
    print(json.dumps(results["targets"], indent=1), flush=True)
    path.write_text(json.dumps(results, indent=1))
    plot(results, path.with_suffix(".png"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
