"""How the diagnosis's cost grows with the bundle: points 300 -> 5,000, frames 1 -> 20.

How the diagnosis's cost grows with the data: seconds and accuracy over a sweep of bundle
sizes (tracked points 300 -> 5,000, frames 1 -> 20), on synthetic bundles with a hidden effect.

    python -m benchmarks diagnose_scale                       # the default sweep (hours on a shared 2 cores)
    python -m benchmarks diagnose_scale --sizes 300x2 3000x11 # chosen cells (POINTSxFRAMES)
    python -m benchmarks diagnose_scale --merge               # summary and plot from the rows file
    python -m benchmarks diagnose_scale --sizes 3000x11 --profile   # where its CPU seconds go (_diagnose_profile.py)

Each cell draws its hidden effect (place, size, ratio) under its own seed from ``--causes``; the
data come from refine.demo_data (a finer quadratic mesh of a larger sheet, solved
independently, Gaussian noise of 0.02 mm) on the 100 x 60 mm region, the point grid's spacing
chosen for the number of points. Every case runs in a fresh process (no compiled program is
shared between cases), one at a time, with ``--threads`` threads (the diagnosis's workers);
``seconds`` are the diagnosis's wall seconds (not the bundle's generation), ``cpu_seconds`` the
process's CPU seconds over them (all threads), with the load average beside them: on a shared
machine the wall seconds measure the load as much as the code, the CPU seconds less so.

Writes benchmarks/results/diagnose_scale.json (rows, a log-log slope of seconds against points x
frames, and ``targets``: a 3,000-point, 11-frame bundle under 180 s on 2 cores; ~300-point
bundles under the former median of 48 s; cost about linear or better in points x frames) and
diagnose_scale.png.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import time
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path


import numpy as np

from benchmarks._cli import QUICK, quick

HERE = Path(__file__).resolve().parent
OUT = HERE / "results"
ROI = (20.0, 10.0, 120.0, 70.0)
DIAGONAL = float(np.hypot(100.0, 60.0))
# (a cell's seed and hidden cause follow its place in this list: new cells go at the end, so the
# older cells keep their cases)
DEFAULT_SIZES = ("300x2", "300x11", "1000x11", "3000x1", "3000x4", "3000x11", "3000x20", "5000x11",
                 "300x1", "300x4", "300x20", "5000x1", "5000x20")
TARGETS = {"seconds_3000x11": 180.0, "seconds_300": 48.0, "slope": 1.0}
CENTROID_TOL, SIZE_TOL = 0.03, 0.10  # accuracy per cell: centroid within 3 % of the diagonal, ratio or area within 10 %


def spacing_for(points: int) -> float:
    """The grid spacing (mm) that puts about ``points`` points on the 100 x 60 mm region."""
    # (100 / s + 1) (60 / s + 1) = n  ->  n s^2 - 160 s - 6000 = 0 ... solved for s
    n = float(points)
    return float((160.0 + np.sqrt(160.0**2 + 4.0 * (n - 1.0) * 6000.0)) / (2.0 * (n - 1.0)))


def cpu_seconds() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def case_bundle(case: dict):
    """``(truth, bundle)`` of a cell: its hidden effect drawn under its seed, the data from
    refine.demo_data's finer solve plus noise."""
    os.environ.setdefault("JAX_PLATFORMS", "cpu")
    from refine.demo_data import random_truth, synthetic_bundle

    truth = random_truth(np.random.default_rng(case["seed"]), case["cause"])
    return truth, synthetic_bundle(truth, seed=case["seed"], spacing=case["spacing"], noise=0.02,
                                   fractions=tuple(np.linspace(0, 1, case["frames"] + 1)[1:]))


def run_case(case: dict) -> dict:
    """Generate one bundle and diagnose it, in a fresh worker process."""
    from refine.diagnosis import DiagnoseConfig, diagnose

    truth, bundle = case_bundle(case)
    load0, cpu0, t0 = os.getloadavg()[0], cpu_seconds(), time.perf_counter()
    d = diagnose(bundle, DiagnoseConfig(workers=case["threads"]), log=lambda m: None)
    seconds, cpu = time.perf_counter() - t0, cpu_seconds() - cpu0
    return {**case, "code": case.get("code") or code_version(), "points": int(bundle.observations.n_points), **score(truth, d),
            "seconds": round(seconds, 2),
            "cpu_seconds": round(cpu, 2), "load_average": [round(load0, 2), round(os.getloadavg()[0], 2)],
            "cells": int(d.model.mesh.n_cells), "chosen": d.chosen.describe()}


def code_version() -> str:
    """The commit of the library code measured, "+dirty" where refine/ or jaxfem/ differ from it."""
    import subprocess

    root = Path(__file__).resolve().parent.parent
    try:
        run = lambda *a: subprocess.run(a, cwd=root, capture_output=True, text=True, check=True).stdout.strip()  # noqa: E731
        return run("git", "rev-parse", "--short", "HEAD") + ("+dirty" if run("git", "status", "--porcelain", "--",
                                                                                  "refine", "jaxfem") else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def accurate(row) -> bool:
    """Right cause, centroid within 3 % of the diagonal, a region's ratio or a hole's area within 10 %."""
    errors = [row.get("ratio_error"), row.get("area_error")]
    return bool(row["right_cause"] and row.get("centroid_error", 1.0) < CENTROID_TOL
                and all(e < SIZE_TOL for e in errors if e is not None))


def score(truth, d) -> dict:
    """Right cause; centroid error (share of the region's diagonal); a region's ratio error or a
    hole's area error (relative); the gain on the validation points."""
    found = d.findings
    out = {"truth": sorted(truth.causes), "found": sorted(f.cause for f in found), "gain": d.errors["gain"]}
    out["right_cause"] = out["truth"] == out["found"]
    shapes = [(i.shape, i.ratio) for i in truth.inclusions] + [(h, 0.0) for h in truth.holes]
    regions = [f for f in found if f.region is not None]
    if shapes and regions:
        shape, ratio = shapes[0]
        f = min(regions, key=lambda f: np.hypot(*(np.subtract(f.region.centroid, shape.params[:2]))))
        out["centroid_error"] = float(np.hypot(*np.subtract(f.region.centroid, shape.params[:2])) / DIAGONAL)
        if ratio > 0 and f.relative_elasticity:
            out["ratio_error"] = float(abs(f.relative_elasticity / ratio - 1))
        elif ratio == 0:
            out["area_error"] = float(abs(f.region.area / shape.area - 1))
    return out


def latest_rows(path: Path) -> list[dict]:
    """The last row of each cell (``size``) in the rows file, in file order."""
    last = {}
    for line in path.read_text().splitlines() if path.exists() else ():
        if line.strip():
            r = json.loads(line)
            last[r["size"]] = r
    return list(last.values())


def slope(rows, key: str = "seconds") -> float | None:
    """Least-squares slope of log(``key``) against log(points x frames)."""
    ok = [r for r in rows if key in r]
    if len({r["points"] * r["frames"] for r in ok}) < 2:
        return None
    x = np.log([r["points"] * r["frames"] for r in ok])
    return float(np.polyfit(x, np.log([r[key] for r in ok]), 1)[0])


def targets(rows, latest=None) -> dict:
    """The targets; the speed targets judged on ``latest`` (the last row of each cell in the
    rows file, whatever its cause: rows of older code stay in the file) where given."""
    timed = rows if latest is None else latest
    big = [r for r in timed if r["frames"] == 11 and 2500 <= r["points"] <= 3500]
    small = [r for r in timed if r["points"] < 400]
    s = slope(rows)
    med = lambda v: float(np.median(v)) if v else None  # noqa: E731
    # wall seconds judge the targets; CPU seconds and the load average say how much of them was the load
    return {
        "3000x11_under_180s": {"target": TARGETS["seconds_3000x11"], "measured": med([r["seconds"] for r in big]),
                               "cpu_seconds": med([r["cpu_seconds"] for r in big]),
                               "load_average": [r["load_average"] for r in big],
                               "pass": bool(big) and med([r["seconds"] for r in big]) < TARGETS["seconds_3000x11"]},
        "300_points_under_48s": {"target": TARGETS["seconds_300"], "measured": med([r["seconds"] for r in small]),
                                 "cpu_seconds": med([r["cpu_seconds"] for r in small]),
                                 "load_average": [r["load_average"] for r in small],
                                 "pass": bool(small) and med([r["seconds"] for r in small]) < TARGETS["seconds_300"]},
        "about_linear": {"target": f"slope of log seconds on log(points x frames) <= {TARGETS['slope']}",
                         "measured": s, "cpu_seconds_slope": slope(rows, "cpu_seconds"),
                         "pass": s is not None and s <= TARGETS["slope"]},
        "right_cause": {"target": "every case", "measured": float(np.mean([r["right_cause"] for r in rows])),
                        "pass": all(r["right_cause"] for r in rows)},
        "accurate": {"target": f"every case: right cause, centroid within {CENTROID_TOL:.0%} of the diagonal, ratio "
                               f"or area within {SIZE_TOL:.0%}",
                     "measured": float(np.mean([accurate(r) for r in rows])) if rows else None,
                     "failed_cells": [r["size"] for r in rows if not accurate(r)],
                     "pass": bool(rows) and all(accurate(r) for r in rows)},
    }


def plot(rows, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, acc) = plt.subplots(1, 2, figsize=(12, 4.5))
    for key, marker, label in (("seconds", "o", "wall s"), ("cpu_seconds", "x", "CPU s (all threads)")):
        x = [r["points"] * r["frames"] for r in rows]
        ax.loglog(x, [r[key] for r in rows], marker, label=label)
    for r in rows:
        ax.annotate(f"{r['points']}x{r['frames']}", (r["points"] * r["frames"], r["seconds"]), fontsize=7)
    ax.axhline(TARGETS["seconds_3000x11"], color="r", ls="--", lw=1, label="3000x11 target (180 s)")
    ax.set_xlabel("points x frames")
    ax.set_ylabel("seconds per diagnosis")
    ax.set_title("diagnosis cost against bundle size (load average in the JSON)")
    ax.legend(fontsize=8)
    x = np.arange(len(rows))
    acc.semilogy(x, [max(r.get("centroid_error", np.nan), 1e-6) for r in rows], "o", label="centroid error / diagonal")
    acc.semilogy(x, [max(r.get("ratio_error") or r.get("area_error") or np.nan, 1e-6) for r in rows], "s",
                 label="ratio or area error (relative)")
    acc.axhline(SIZE_TOL, color="r", ls="--", lw=1, label=f"{SIZE_TOL:.0%}")
    acc.axhline(CENTROID_TOL, color="m", ls=":", lw=1, label=f"{CENTROID_TOL:.0%} of the diagonal")
    acc.set_xticks(x, [f"{r['size']}\n{r['cause'].split('-')[0]}{'' if r['right_cause'] else ' WRONG'}" for r in rows],
                   fontsize=6, rotation=90)
    acc.set_title("accuracy per cell")
    acc.legend(fontsize=7)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)


def main(argv=None) -> int:
    argv = quick(argv, ["--sizes", "300x1", "--causes", "hole", "--rows", str(QUICK / "diagnose_scale.jsonl")])
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--sizes", nargs="+", default=list(DEFAULT_SIZES), help="cells POINTSxFRAMES")
    p.add_argument("--causes", nargs="+", default=["softer-region", "hole", "stiffer-region"],
                   help="hidden effects, drawn in turn over the cells")
    p.add_argument("--threads", type=int, default=2, help="the diagnosis's workers")
    p.add_argument("--rows", default=str(OUT / "diagnose_scale.jsonl"), help="rows file (JSONL, resumable)")
    p.add_argument("--merge", action="store_true", help="only summarise the rows file")
    p.add_argument("--rerun", action="store_true",
                   help="run the cells even where the rows file has them (the new row replaces the old in the JSON)")
    p.add_argument("--code", default=None,
                   help="the commit measured, stored in the rows (default: this checkout's; give it where "
                        "PYTHONPATH puts another tree's refine first, e.g. a before/after pair)")
    p.add_argument("--profile", action="store_true",
                   help="profile the cells instead (cProfile, compilations, CPU s per stage; "
                        "results/diagnose_profile_SIZE.json; no row written)")
    args = p.parse_args(argv)
    rows_path = Path(args.rows)
    done = {}
    if rows_path.exists():
        done = {(r["size"], r["cause"]): r for r in map(json.loads, rows_path.read_text().splitlines()) if r}
    if not args.merge:
        cases = []
        for i, size in enumerate(args.sizes):
            # a default cell is the same case whichever cells are asked for
            k = DEFAULT_SIZES.index(size) if size in DEFAULT_SIZES else len(DEFAULT_SIZES) + i
            points, frames = map(int, size.split("x"))
            cause = args.causes[k % len(args.causes)]
            if (size, cause) in done and not (args.profile or args.rerun):
                continue
            cases.append({"size": size, "cause": cause, "seed": 700 + k, "frames": frames,
                          "spacing": round(spacing_for(points), 4), "threads": args.threads,
                          **({"code": args.code} if args.code else {})})
        for case in cases:
            if args.profile:
                from benchmarks._diagnose_profile import profile_case
                from refine.diagnosis import DiagnoseConfig

                row = profile_case(case_bundle(case)[1], DiagnoseConfig(workers=case["threads"]), case["size"], OUT)
                print(json.dumps({k: row[k] for k in ("label", "cpu_s", "wall_s", "load", "compiles", "compile_s",
                                                      "chosen")}), flush=True)
                continue
            with ProcessPoolExecutor(1, mp_context=get_context("spawn")) as pool:
                row = pool.submit(run_case, case).result()
            print(json.dumps(row), flush=True)
            with rows_path.open("a") as fh:
                fh.write(json.dumps(row) + "\n")
            done[(case["size"], case["cause"])] = row
    if args.profile:
        return 0
    rows = sorted(done.values(), key=lambda r: r["points"] * r["frames"])
    out = {"benchmark": "diagnose_scale", "machine": {"cores": os.cpu_count()}, "rows": rows,
           "slope_seconds_on_points_x_frames": slope(rows), "targets": targets(rows, latest_rows(rows_path))}
    OUT.mkdir(exist_ok=True)
    (OUT / "diagnose_scale.json").write_text(json.dumps(out, indent=2))
    plot(rows, OUT / "diagnose_scale.png")
    print(json.dumps(out["targets"], indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
