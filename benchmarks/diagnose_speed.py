"""Where a diagnosis's seconds go: one benchmarks/diagnose.py case diagnosed in this process, with
the number of XLA compilations and their CPU-side seconds (``jax.monitoring``), the process's CPU
and wall seconds, the load average and the result (cause, centroid, ratio or area errors).

    python benchmarks/diagnose_speed.py --label quiet      # the median over the default ~300-point cases
    python benchmarks/diagnose_speed.py --case 5/0.02/stiffer-region/0 --label after
    python benchmarks/diagnose_speed.py --case 5/0.02/hole/0 --cache /tmp/jaxcache --label cache-warm

Several cases (``--cases``; default: a stiffer region, a softer region and a hole on the 5 mm grid,
273 points, 4 frames) run one after another, each in a fresh process (as a user's ``nonrigid
diagnose``: no program compiled by an earlier case). Each run appends one row to ``--rows``
(default results/diagnose_speed_rows.jsonl) and rewrites ``--out`` (results/diagnose_speed.json)
from all rows, with a ``targets`` section (issue 22 item 2: the ~300-point bundles faster than
the former median of 48 s: the median wall seconds over the cases of one label, the latest row
per case). Each row keeps the wall and CPU seconds at every progress line of the diagnosis
(``stages``: where the seconds go, stage by stage). See benchmarks/README.md, "diagnose_speed.py".
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
# this folder last on the path: a script here named like a package would shadow it
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != HERE] + [str(HERE)]
OUT = HERE / "results"
TARGET_WALL_S = 48.0
#: the ~300-point cases of the median (benchmarks/diagnose.py's 5 mm grid, 273 points, 4 frames)
DEFAULT_CASES = ("5/0.02/stiffer-region/0", "5/0.02/softer-region/0", "5/0.02/hole/0")
#: a compilation longer than this (wall seconds) counts as a program (the solve's programs take
#: 2-10 s each; an array operation run eagerly compiles in milliseconds)
LARGE_COMPILE_S = 1.0


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def _commit() -> str:
    try:
        return subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=HERE, capture_output=True,
                              text=True).stdout.strip() or "?"
    except OSError:
        return "?"


def run(case_key: str, label: str, cache: str | None, workers: int, linear_solver: str = "auto") -> dict:
    """Diagnose one case (``SPACING/NOISE/CAUSE/K``) and return its row."""
    import jax

    compiles = {"n": 0, "seconds": 0.0, "large": 0, "large_seconds": 0.0}

    def listen(event, duration, **kw):
        if event.endswith("backend_compile_duration"):
            compiles["n"] += 1
            compiles["seconds"] += duration
            if duration > LARGE_COMPILE_S:
                compiles["large"] += 1
                compiles["large_seconds"] += duration

    jax.monitoring.register_event_duration_secs_listener(listen)
    if cache:
        from jaxfem import compilation_cache

        compilation_cache(cache)
    from diagnose import CAUSES, score
    from _diagnose_oracle import _case_bundle
    from refine.diagnosis import DiagnoseConfig, diagnose

    spacing, noise, cause, k = case_key.split("/")
    seed = 1000 * int(float(spacing)) + 100 * CAUSES.index(cause) + int(k)
    case = {"spacing": float(spacing), "noise": float(noise), "cause": cause, "k": int(k), "seed": seed, "frames": 4}
    truth, bundle = _case_bundle(case)
    compiles.update(n=0, seconds=0.0, large=0, large_seconds=0.0)  # the diagnosis's, not the bundle's
    load0 = os.getloadavg()[0]
    c0, w0 = _cpu(), time.perf_counter()
    stages = []  # [wall s, CPU s, what] at each progress line: the stages' seconds (a stage ends at its line)

    def log(msg):
        stages.append([round(time.perf_counter() - w0, 1), round(_cpu() - c0, 1), msg.split("] ", 1)[-1][:60]])

    d = diagnose(bundle, config=DiagnoseConfig(workers=workers, linear_solver=linear_solver), log=log)
    cpu, wall = _cpu() - c0, time.perf_counter() - w0
    s = score(truth, d)
    return {"label": label, "code": _commit(), "case": case_key, "points": int(bundle.observations.n_points),
            "workers": workers, "linear_solver": linear_solver, "cache": bool(cache), "wall": round(wall, 1), "cpu": round(cpu, 1),
            "compiles": compiles["n"], "compile_seconds": round(compiles["seconds"], 1),
            "large_compiles": compiles["large"], "large_compile_seconds": round(compiles["large_seconds"], 1),
            "load": [round(load0, 2), round(os.getloadavg()[0], 2)], "found": s["found"], "passed": s["passed"],
            "centroid": s["centroid_error"], "ratio": s["ratio_error"], "area": s["area_error"], "gain": s["gain"],
            "chosen": d.chosen.describe(), "stages": stages}


def median_target(rows: list[dict], label: str) -> dict:
    """The target judged on ``label``'s rows: the median wall (and CPU) seconds over its cases,
    the latest row of each case; passes with at least 3 cases under :data:`TARGET_WALL_S`."""
    latest = {r["case"]: r for r in rows if r["label"] == label}
    walls, cpus = [r["wall"] for r in latest.values()], [r["cpu"] for r in latest.values()]
    median = lambda v: float(np.median(v)) if v else None  # noqa: E731
    return {"target_s": TARGET_WALL_S, "label": label, "cases": sorted(latest), "median_wall_s": median(walls),
            "median_cpu_s": median(cpus), "loads": [latest[c]["load"] for c in sorted(latest)],
            "right_results": [latest[c]["passed"] for c in sorted(latest)],
            "pass": len(latest) >= 3 and median(walls) < TARGET_WALL_S}


def write(rows: list[dict], out: Path, label: str | None = None) -> dict:
    """The results JSON (rows and targets) and its plot beside it (CPU seconds and programs
    compiled per row). ``label``: whose median judges the target (default: the last row's)."""
    after = [r for r in rows if r["label"] != "before"]
    best = min(after, key=lambda r: r["wall"], default=None)
    label = label or (rows[-1]["label"] if rows else None)
    result = {"benchmark": "diagnose speed (issue 22 item 2)", "rows": rows,
              "targets": {"~300-point bundles: median wall under 48 s": median_target(rows, label),
                          "300-point bundle under 48 s wall (best single row, for reference)": {
                  "target_s": TARGET_WALL_S, "best_wall_s": best and best["wall"], "its_cpu_s": best and best["cpu"],
                  "its_load": best and best["load"],
                  "pass": best is not None and best["wall"] < TARGET_WALL_S}}}
    out.write_text(json.dumps(result, indent=1))
    _plot(rows, out.with_suffix(".png"))
    return result


def _plot(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = [f"{r['label']} {r['code'].split()[0]}{' cache' if r.get('cache') else ''}" for r in rows]
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.5))
    axes[0].barh(names, [r["cpu"] for r in rows])
    axes[0].set_xlabel("CPU s of the diagnosis")
    axes[1].barh(names, [r.get("large_compiles", float("nan")) for r in rows])
    axes[1].set_xlabel("compilations > 1 s")
    for ax in axes:
        ax.invert_yaxis()
    fig.suptitle(f"{rows[0]['case']}, {rows[0]['points']} points (load average in the JSON)")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--case", default=None, help="one case SPACING/NOISE/CAUSE/K of benchmarks/diagnose.py "
                                                "(in this process)")
    p.add_argument("--cases", nargs="+", default=list(DEFAULT_CASES),
                   help="cases run one after another, each in a fresh process (default: %(default)s)")
    p.add_argument("--label", default="after", help="what code this row measures (e.g. before, after)")
    p.add_argument("--cache", default=None, help="JAX persistent compilation cache folder (jaxfem.compilation_cache)")
    p.add_argument("--workers", type=int, default=2, help="DiagnoseConfig.workers (the command line's default: 2)")
    p.add_argument("--linear-solver", default="auto", help="DiagnoseConfig.linear_solver")
    p.add_argument("--rows", type=Path, default=OUT / "diagnose_speed_rows.jsonl")
    p.add_argument("--out", type=Path, default=OUT / "diagnose_speed.json")
    a = p.parse_args()
    for case in [a.case] if a.case else a.cases:
        args = (case, a.label, a.cache, a.workers, a.linear_solver)
        if a.case:
            row = run(*args)
        else:  # a fresh process per case: nothing compiled by the one before
            with ProcessPoolExecutor(1, mp_context=get_context("spawn")) as pool:
                row = pool.submit(run, *args).result()
        print(json.dumps(row), flush=True)
        with open(a.rows, "a") as fh:
            fh.write(json.dumps(row) + "\n")
    result = write([json.loads(line) for line in a.rows.read_text().splitlines() if line.strip()], a.out, a.label)
    print(json.dumps(result["targets"], indent=1))


if __name__ == "__main__":
    main()
