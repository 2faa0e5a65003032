"""Diagnosis over random hidden cases per cause: right causes, false alarms, errors, gain, seconds.

Diagnosis benchmark: rates of right causes and false alarms, localisation and ratio errors,
gain and seconds, over random hidden cases per cause, at two grid densities and two noise levels.

    python -m benchmarks diagnose                          # 20 cases per cell, one worker per core
    python -m benchmarks diagnose --cases 1 --workers 1 --threads 2   # a quick look
    python -m benchmarks diagnose --cases-per-cell 20 --workers 16    # the 480 cases on 16 cores
    python -m benchmarks diagnose --scheduler tcp://HOST:8786         # on a Dask cluster
    python -m benchmarks diagnose --summarise benchmarks/results/diagnose.json  # summary from stored rows
    python -m benchmarks diagnose --oracle --summarise benchmarks/results/diagnose.json
                                                           # what the data allow, per case

Each case draws its hidden effect (location, size, ratio) under its own seed; data come from a
finer quadratic mesh of a larger sheet, with noise; the inversion uses linear triangles on the
tracked region (and quadratic ones for the chosen model's final refit). Cases are tasks of the
batch runner (:func:`refine.batch.run_tasks`, Dask): a local cluster of ``--workers`` spawned
processes of ``--threads`` cores each, or the workers of a Dask scheduler (``--scheduler``). Each
finished case is appended to the rows file (JSONL) at once, so a run stopped early keeps what
finished and a second run with the same rows file resumes (cases already there are skipped); a case
that fails is a row with its error. Cases are submitted case index first, so a run stopped early has
about as many cases in every cell.

Writes benchmarks/results/diagnose.json (and diagnose.png) from all rows: per cell (spacing,
noise, cause) the counts and rates, with the machine the rows were measured on. ``seconds`` are
wall seconds of one diagnosis in one worker process (of ``--threads`` threads), on that machine, at the
load average stored beside each row.

Some cases cannot meet the issue's criteria whatever the method: a stiff region's ratio hardly
changes the motion once it is several times the background's, and noise at the driving boundary
points and at the validation points bounds the gain. ``--oracle`` measures that per case
(``oracle_case``: the true model's gain and the Cramer-Rao bound of each ratio) and the summary
gives the rates also over the cases where the criteria are attainable.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

from benchmarks._diagnose_oracle import (AREA_TOL, CENTROID_TOL, GAIN_MIN, RATIO_TOL, _case_bundle, _case_truth, _med,
                              against_oracle, oracle_case)
from benchmarks._diagnose_plot import plot
from benchmarks._cli import QUICK, quick  # noqa: E402

DIAGONAL = float(np.hypot(100.0, 60.0))
OUT = Path(__file__).parent / "results"
ORACLE_ROWS = OUT / "diagnose_oracle.jsonl"  # oracle_case's rows, joined with the cases' rows by case
CAUSES = ("none", "stiffer-region", "softer-region", "hole", "two-regions", "rectangle")


def case_key(c: dict) -> str:
    return f"{c['spacing']:g}/{c['noise']:g}/{c['cause']}/{c['k']}"


def all_cases(args) -> list[dict]:
    """Every case (those of ``args.only`` where given), case index outermost (a run stopped early is
    balanced over the cells)."""
    out = []
    for k in range(args.cases):
        for spacing in args.spacings:
            for noise in args.noises:
                for cause in args.causes:
                    seed = 1000 * int(spacing) + 100 * CAUSES.index(cause) + k
                    out.append({"spacing": spacing, "noise": noise, "cause": cause, "k": k, "seed": seed,
                                "frames": args.frames})
    only = set(args.only or [])
    return [c for c in out if case_key(c) in only] if only else out


def score(truth, d) -> dict:
    """Right cause, centroid, ratio and area errors of one case, and whether it passes."""
    found = d.findings
    want = sorted(truth.causes)
    row = {"found": [f["cause"] for f in found], "truth": want,
           "right_cause": sorted(f["cause"] for f in found) == want,
           "false_alarm": bool(found) and not want, "missed": bool(want) and not found,
           "gain": d.errors["gain"], "seconds": d.seconds,
           "centroid_error": [], "ratio_error": [], "signed_ratio_error": [], "area_error": [],
           "signed_area_error": [], "truth_ratio": [], "truth_size": [], "ratio_std": []}
    shapes = [(inc.shape, inc.ratio) for inc in truth.inclusions] + [(h, 0.0) for h in truth.holes]
    for shape, ratio in shapes:
        cands = [f for f in found if f["region"]]
        if not cands:
            continue
        centre = np.asarray(shape.params[:2])  # Ellipse and Rect alike
        f = min(cands, key=lambda f: np.hypot(*(np.asarray(f["region"]["centroid"]) - centre)))
        row["centroid_error"].append(float(np.hypot(*(np.asarray(f["region"]["centroid"]) - centre)) / DIAGONAL))
        row["truth_size"].append(float(np.sqrt(shape.area)))
        area = f["region"]["area"] / shape.area - 1
        if ratio > 0:
            row["ratio_std"].append(f.get("relative_elasticity_std"))
            row["ratio_error"].append(float(abs(f["relative_elasticity"] / ratio - 1)))
            row["signed_ratio_error"].append(float(f["relative_elasticity"] / ratio - 1))
            row["truth_ratio"].append(float(ratio))
        else:
            row["area_error"].append(float(abs(area)))
        row["signed_area_error"].append(float(area))
    if not want:
        row["passed"] = not found
    else:
        n = len(shapes)
        row["passed"] = bool(
            row["right_cause"] and len(row["centroid_error"]) == n
            and max(row["centroid_error"]) < CENTROID_TOL
            and all(e < RATIO_TOL for e in row["ratio_error"]) and all(e < AREA_TOL for e in row["area_error"])
            and (row["gain"] or 0) >= GAIN_MIN)
    return row


def run_case(case: dict) -> dict:
    """Generate one bundle and diagnose it (a task on a worker)."""
    from refine.diagnosis import DiagnoseConfig, diagnose

    t0 = time.perf_counter()
    truth, bundle = _case_bundle(case)
    try:
        d = diagnose(bundle, config=DiagnoseConfig(workers=case.get("threads", 1)), log=lambda m: None)
    except Exception as e:  # noqa: BLE001 - a failed diagnosis is a failed case, recorded as such
        return error_row(case, e, time.perf_counter() - t0, truth)
    row = {**case, **score(truth, d)}
    row["points"] = int(bundle.observations.n_points)
    row["data_seconds"] = time.perf_counter() - t0 - d.seconds
    row["load_average"] = [round(x, 2) for x in os.getloadavg()]
    row["chosen"] = d.chosen.describe()
    row["hypotheses"] = [{"hypothesis": f.describe(), "k": f.k, "bic": round(f.bic, 2), "chi2_fit": round(f.chi2_fit, 2),
                          "chi2_holdout": round(f.chi2_holdout, 2)} for f in d.tried]
    return row


def error_row(case: dict, e: BaseException, seconds: float | None = None, truth=None) -> dict:
    """The row of a case that failed (its diagnosis raised, or its task did not return: then
    ``seconds`` is None): a missed case, with the error."""
    truth = _case_truth(case) if truth is None else truth
    return {**case, "error": f"{type(e).__name__}: {e}", "passed": False, "right_cause": False,
            "false_alarm": False, "missed": True, "found": [], "truth": sorted(truth.causes), "gain": None,
            "seconds": seconds, "centroid_error": [], "ratio_error": [], "signed_ratio_error": [], "area_error": [],
            "signed_area_error": [], "truth_ratio": [], "truth_size": [],
            "load_average": [round(x, 2) for x in os.getloadavg()], "chosen": ""}


def _code_version() -> str:
    """The commit the library code of this run is at (with "+dirty" when the tree differs from it)."""
    import subprocess

    root = Path(__file__).resolve().parent.parent
    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=root, capture_output=True, text=True,
                              check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--", "jaxfem", "refine"], cwd=root,
                               capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return head + ("+dirty" if dirty else "")


def _read_rows(paths) -> list[dict]:
    """The rows of results JSONs and rows JSONLs ``paths``, one per case: a later row of a case
    replaces an earlier one; a line cut short (a run killed while writing) is skipped."""
    rows = {}
    for p in paths:
        p = Path(p)
        if p.suffix == ".json":  # a results file: its rows
            for g in json.loads(p.read_text())["groups"]:
                rows.update((case_key(r), r) for r in g["rows"])
        elif p.exists():
            for line in p.read_text().splitlines():
                try:
                    r = json.loads(line)
                except json.JSONDecodeError:
                    continue
                rows[case_key(r)] = r
    return list(rows.values())


def _within_3_std(rows):
    """Share of fitted ratios whose reported standard error (x3) covers the truth."""
    hits = [abs(e) * t < 3 * s for r in rows for e, t, s in zip(r["signed_ratio_error"], r["truth_ratio"],
                                                                  r.get("ratio_std", [])) if s is not None]
    return float(np.mean(hits)) if hits else None


def summarise(rows) -> dict:
    """Counts, rates and medians of one cell's rows."""
    flat = lambda key: [x for r in rows for x in r[key]]  # noqa: E731
    gains = [r["gain"] for r in rows if r["gain"] and r["truth"]]  # homogeneous cases have nothing to gain
    seconds = [r["seconds"] for r in rows if r["seconds"] is not None]  # None: a task that did not return
    return {"cases": len(rows), "errors": sum("error" in r for r in rows), "pass_rate": float(np.mean([r["passed"] for r in rows])),
            "right_cause_rate": float(np.mean([r["right_cause"] for r in rows])),
            "false_alarm_rate": float(np.mean([r["false_alarm"] for r in rows])),
            "missed_rate": float(np.mean([r["missed"] for r in rows])),
            "median_centroid_error_of_diagonal": _med(flat("centroid_error")),
            "centroid_within_3pct_rate": float(np.mean([e < CENTROID_TOL for e in flat("centroid_error")]))
            if flat("centroid_error") else None,
            "median_ratio_error": _med(flat("ratio_error")),
            "median_signed_ratio_error": _med(flat("signed_ratio_error")),
            "ratio_within_10pct_rate": float(np.mean([e < RATIO_TOL for e in flat("ratio_error")]))
            if flat("ratio_error") else None,
            "ratio_within_3_std_rate": _within_3_std(rows),
            "median_hole_area_error": _med(flat("area_error")),
            "median_signed_area_error": _med(flat("signed_area_error")),
            "median_gain": _med(gains), "gain_2x_rate": float(np.mean([g >= GAIN_MIN for g in gains])) if gains else None,
            **against_oracle(rows),
            "median_seconds": _med(seconds),
            "max_seconds": float(max(seconds)) if seconds else None}


# The benchmark's targets over all cases (issue 5's criteria per case, rates over the run): the right
# cause named, no finding on a homogeneous sheet, the centroid within 3 % of the diagonal, and the
# extended model predicting held-out points at least 2x better; ratios within 10 % are reported but
# not a target (the Cramer-Rao bound of a small region's ratio on a 10 mm grid is wider).
TARGETS = {"right_cause_rate": (">=", 0.9), "false_alarm_rate": ("<=", 0.05),
           "centroid_within_3pct_rate": (">=", 0.9), "gain_2x_rate": (">=", 0.75)}


def targets(overall: dict | None) -> dict:
    """Pass/fail of each of :data:`TARGETS` on the overall summary."""
    out = {}
    for key, (op, bound) in TARGETS.items():
        value = None if overall is None else overall.get(key)
        ok = value is not None and (value >= bound if op == ">=" else value <= bound)
        out[key] = {"target": f"{op} {bound}", "value": value, "pass": bool(ok)}
    return out


def write_results(rows, machine: dict, settings: dict, out: Path = OUT / "diagnose.json") -> dict:
    """Summarise ``rows`` per cell and overall; write ``out`` (JSON) and the plot beside it."""
    oracle = {case_key(o): o for o in _read_rows([ORACLE_ROWS]) if "oracle_error" not in o}
    rows = [{**r, **oracle.get(case_key(r), {})} for r in rows]
    cells = {}
    for r in rows:
        cells.setdefault((r["spacing"], r["noise"], r["cause"]), []).append(r)
    groups = [{"spacing": s, "noise": n, "cause": c, **summarise(rs), "rows": sorted(rs, key=lambda r: r["k"])}
              for (s, n, c), rs in sorted(cells.items(), key=lambda kv: (kv[0][0], kv[0][1], CAUSES.index(kv[0][2])))]
    results = {"settings": settings, "machine": machine, "run_note": settings.get("note", ""),
               "note": ("seconds: wall seconds of one diagnosis (data generation excluded, JIT compilation "
                        f"included) in one worker process of {machine.get('threads_per_worker', 1)} thread(s) "
                        "(each row's 'threads') on the machine below, at the load average stored in each row"),
               "cases_per_cell": sorted({g["cases"] for g in groups}),
               "overall": summarise(rows) if rows else None, "groups": groups}
    results["targets"] = targets(results["overall"])
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(results, indent=1))
    plot(results, out.with_suffix(".png"))
    return results


def _parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description="The diagnosis benchmark (see the module docstring).")
    ap.add_argument("--cases", "--cases-per-cell", type=int, default=20,
                    help="cases per cell (cause, spacing and noise level): k = 0 .. N-1")
    ap.add_argument("--spacings", type=float, nargs="+", default=[10.0, 5.0])
    ap.add_argument("--noises", type=float, nargs="+", default=[0.02, 0.05])
    ap.add_argument("--causes", nargs="+", default=list(CAUSES), choices=CAUSES, metavar="CAUSE",
                    help=f"of {', '.join(CAUSES)}")
    ap.add_argument("--only", nargs="+", metavar="SPACING/NOISE/CAUSE/K",
                    help="run only these cases of the others, e.g. 10/0.02/hole/2 (to rerun a few cases)")
    ap.add_argument("--frames", type=int, default=4)
    ap.add_argument("--workers", type=int, default=None,
                    help="worker processes of the local cluster (default: one per --threads cores)")
    ap.add_argument("--threads", type=int, default=1,
                    help="cores of each worker: 1 pins XLA and BLAS to one thread and fits one hypothesis at a "
                         "time; N > 1 gives XLA and BLAS N threads and fits N hypotheses side by side (one "
                         "diagnosis on N cores, as the issue's time target counts it: --workers 1 --threads 2)")
    ap.add_argument("--scheduler", default=None,
                    help="address of a Dask scheduler (tcp://HOST:8786) whose workers run the cases, instead of a "
                         "local cluster (start them with one thread each: see refine.batch.cluster)")
    ap.add_argument("--rows", default=str(OUT / "diagnose_rows.jsonl"), help="JSONL of finished cases (resumed)")
    ap.add_argument("--summarise", nargs="+", default=None, metavar="ROWS",
                    help="run nothing: summarise the rows of these files (a results JSON or rows JSONL; a later "
                         "file's row of a case replaces an earlier one, e.g. a few cases rerun with --only)")
    ap.add_argument("--out", default=str(OUT / "diagnose.json"),
                    help="results JSON (the plot goes beside it); give another path for a partial or experimental "
                         "run, so the full benchmark's results stay as they are")
    ap.add_argument("--oracle", action="store_true",
                    help=f"compute what the data allow (oracle_case) for the cases of --summarise (or --rows) not "
                         f"yet in {ORACLE_ROWS.name}, then summarise them with it (e.g. --oracle --summarise "
                         "benchmarks/results/diagnose.json re-summarises the committed run)")
    ap.add_argument("--no-progress", action="store_true", help="no progress bar")
    ap.add_argument("--note", default="", help="what the reader must know about this run (stored in the JSON)")
    return ap


def main(argv=None) -> int:
    argv = quick(argv, ["--cases", "1", "--spacings", "10", "--noises", "0.05", "--causes", "hole", "--rows", str(QUICK / "diagnose_rows.jsonl"), "--out", str(QUICK / "diagnose.json")])
    ap = _parser()
    args = ap.parse_args(argv)
    every = {case_key(c) for c in all_cases(argparse.Namespace(**{**vars(args), "only": None}))}
    unknown = sorted(set(args.only or []) - every)
    if unknown:
        ap.error(f"--only: no such case among --cases/--spacings/--noises/--causes: {', '.join(unknown)} "
                 "(keys are SPACING/NOISE/CAUSE/K as in 10/0.02/hole/2)")
    if args.oracle:
        done = {case_key(r) for r in _read_rows([ORACLE_ROWS]) if "oracle_error" not in r}
        todo = [{k: r[k] for k in ("spacing", "noise", "cause", "k", "seed", "frames")}
                for r in _read_rows(args.summarise or [args.rows])]  # the cases summarised
        _run(oracle_case, [c for c in todo if case_key(c) not in done], ORACLE_ROWS, args, _oracle_failed,
             lambda row: f"k {row['k']}: oracle gain {row.get('oracle_gain') or 0:.2f} "
                         f"ratio std {row.get('oracle_ratio_std')}")
    if args.summarise is not None or args.oracle:
        rows = _read_rows(args.summarise or [args.rows])
        settings, machine = vars(args), None
        earlier = [p for p in args.summarise or [] if p.endswith(".json")]
        if earlier:  # re-summarised: the rows' own run settings stay, with this run's note beside them
            old = json.loads(Path(earlier[0]).read_text())
            settings, machine = {**old["settings"], "resummarised": vars(args)}, old["machine"]
        write_results(rows, machine or _machine(args), settings, args.out)
        print(f"{len(rows)} rows summarised")
        return 0
    _run(run_case, cases_to_run(args), args.rows, args, error_row, lambda row: (
        f"seed {row['seed']}: found {row['found']} gain {row['gain'] or 0:.2f} {'PASS' if row['passed'] else 'fail'} "
        f"{row['seconds'] or 0:.0f} s load {row['load_average'][0]}" + (f" {row['error']}" if "error" in row else "")))
    write_results(_read_rows([args.rows]), _machine(args), vars(args), args.out)
    return 0


def cases_to_run(args) -> list[dict]:
    """The cases of ``args`` (:func:`all_cases`) not yet in its rows file ``args.rows`` (a second
    run resumes the first), each with the run's ``threads`` and library ``code`` version."""
    done = {case_key(r) for r in _read_rows([args.rows])}
    code = _code_version()
    return [{**c, "threads": args.threads, "code": code} for c in all_cases(args) if case_key(c) not in done]


def _workers(args) -> int | None:
    """Worker processes of the local cluster (None with a scheduler: its workers)."""
    if args.scheduler:
        return None
    from refine.batch.cluster import cores

    return args.workers or max(1, cores() // args.threads)


def _machine(args) -> dict:
    out = {"platform": platform.platform(), "processor": platform.processor() or platform.machine(),
           "cpu_count": os.cpu_count(), "workers": _workers(args), "threads_per_worker": args.threads}
    return {**out, "scheduler": args.scheduler} if args.scheduler else out


def _oracle_failed(case: dict, e: BaseException) -> dict:
    """The oracle row of a case whose ``oracle_case`` did not return (run again by the next --oracle)."""
    row = {k: case[k] for k in ("spacing", "noise", "cause", "k", "seed")}
    return {**row, "oracle_error": f"{type(e).__name__}: {e}"}


def _run(fn, todo, path, args, failed, line):
    """``fn(case)`` for the cases ``todo`` on the batch runner's cluster (a local one of
    :func:`_workers` processes of ``args.threads`` cores, or ``args.scheduler``'s); each row
    appended to ``path`` (JSONL) as it finishes, and a ``line`` about it printed."""
    from refine.batch import run_tasks

    where = args.scheduler or f"{_workers(args)} local workers of {args.threads} thread(s)"
    print(f"{len(todo)} cases to run on {where}; rows to {path}", flush=True)
    try:  # the workers need refine only: this script's helpers travel with its functions
        import cloudpickle  # Dask's; without Dask, run_tasks says how to install it

        cloudpickle.register_pickle_by_value(sys.modules[_case_bundle.__module__])
    except ImportError:
        pass
    run_tasks(fn, [(c,) for c in todo], path, lambda task, e: failed(task[0], e), scheduler=args.scheduler,
              workers=_workers(args), threads=args.threads, gpus=(), progress=not args.no_progress, desc="cases",
              line=lambda row: f"{row['spacing']:g} mm noise {row['noise']:g} {row['cause']:15s} {line(row)}")


if __name__ == "__main__":
    raise SystemExit(main())
