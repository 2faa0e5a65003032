"""Where one diagnosis's seconds go: XLA compilations, CPU and wall seconds per case.

Where a diagnosis's seconds go: one benchmarks/diagnose.py case diagnosed in this process, with
the number of XLA compilations and their CPU-side seconds (``jax.monitoring``), the process's CPU
and wall seconds, the load average and the result (cause, centroid, ratio or area errors).

    python -m benchmarks diagnose_speed --label quiet      # the median over the default ~300-point cases
    python -m benchmarks diagnose_speed --case 5/0.02/stiffer-region/0 --label after
    python -m benchmarks diagnose_speed --case 5/0.02/hole/0 --cache /tmp/jaxcache --label cache-warm
    python -m benchmarks diagnose_speed --label s23 --baseline-tree /tmp/base_df5f359 --baseline-code df5f359
    python -m benchmarks diagnose_speed --case 5/0.02/hole/0 --profile   # where its CPU seconds go (no row)

Several cases (``--cases``; default: a stiffer region, a softer region and a hole on the 5 mm grid,
273 points, 4 frames) run one after another, each in a fresh process (as a user's ``nonrigid
diagnose``: no program compiled by an earlier case). Each run appends one row to ``--rows``
(default results/diagnose_speed_rows.jsonl) and rewrites ``--out`` (results/diagnose_speed.json)
from all rows, with a ``targets`` section (issue 22 item 2: the ~300-point bundles faster than
the former median of 48 s: the median wall seconds over the cases of one label, the latest row
per case). Each row keeps the wall and CPU seconds at every progress line of the diagnosis
(``stages``: where the seconds go, stage by stage).

``--baseline-tree DIR`` (with ``--cases``) measures the issue's own code on this machine beside this
one: DIR is a checkout of an older commit (``git archive df5f359 | tar -x -C DIR``; name it with
``--baseline-code``). The cases' bundles are generated once by this code and written in the bundle
format (full precision); for each case this code and DIR's each diagnose that bundle in a fresh
process (``PYTHONPATH=DIR`` for the latter), alternating which goes first, one at a time, so both
rows of a case see the same load. Rows record a digest of the bundle diagnosed and the hidden
effect, and the JSON's ``targets`` judge "faster than the issue's code on the same machine" on the
medians of the two codes' rows of one label, apart from the absolute 48 s entry (a wall target set
on another machine). See benchmarks/README.md, "diagnose_speed.py".
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import resource
import subprocess
import sys
import time
import tempfile
from pathlib import Path

import numpy as np

from benchmarks._subprocess import command, environment
from benchmarks._cli import QUICK, quick  # noqa: E402

HERE = Path(__file__).resolve().parent
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


def _case(case_key: str) -> dict:
    from benchmarks.diagnose import CAUSES

    spacing, noise, cause, k = case_key.split("/")
    seed = 1000 * int(float(spacing)) + 100 * CAUSES.index(cause) + int(k)
    return {"spacing": float(spacing), "noise": float(noise), "cause": cause, "k": int(k), "seed": seed, "frames": 4}


def _truth(case: dict):
    """The case's hidden effect drawn under its seed by the ``refine`` imported (this code's or a
    baseline tree's: the draw is the same, the row records it)."""
    try:
        from refine.demo_data import random_truth
    except ImportError:  # the issue's code (df5f359): one module
        from refine.demo_data import random_truth
    return random_truth(np.random.default_rng(case["seed"]), case["cause"])


def _truth_key(truth) -> list:
    """The hidden shapes' parameters and ratios (0 for a hole): equal rows diagnosed one effect."""
    shapes = [(inc.shape, inc.ratio) for inc in truth.inclusions] + [(h, 0.0) for h in truth.holes]
    return [[float(v) for v in shape.params] + [float(ratio)] for shape, ratio in shapes]


def bundle_digest(bundle) -> str:
    """A digest of what a diagnosis sees of a bundle (point ids, positions, roles, displacements)."""
    o = bundle.observations
    h = hashlib.sha256()
    for a in (o.ids, o.reference, o.displacements):
        h.update(np.ascontiguousarray(np.asarray(a, dtype=float)).tobytes())
    h.update(repr([str(r) for r in o.roles]).encode())
    return h.hexdigest()[:16]


def write_bundles(case_keys: list[str], folder: Path) -> dict:
    """Generate the cases' bundles with this code and write them under ``folder`` (one directory
    per case); read back, each must give the same digest (the format writes full precision)."""
    from benchmarks._diagnose_oracle import _case_bundle
    from refine.bundle import read_bundle, write_bundle

    out = {}
    for key in case_keys:
        _, bundle = _case_bundle(_case(key))
        path = write_bundle(folder / key.replace("/", "_"), bundle)
        if bundle_digest(read_bundle(path)) != bundle_digest(bundle):
            raise RuntimeError(f"{key}: the bundle read back from {path} differs from the one generated")
        out[key] = str(path)
    return out


def _diagnoser():
    try:
        from refine.diagnosis import DiagnoseConfig, diagnose
    except ImportError:  # the issue's code (df5f359)
        from refine.diagnose import DiagnoseConfig, diagnose
    return DiagnoseConfig, diagnose


def run(case_key: str, label: str, cache: str | None, workers: int, linear_solver: str = "auto",
        bundle_dir: str | None = None, code: str | None = None, role: str = "main") -> dict:
    """Diagnose one case (``SPACING/NOISE/CAUSE/K``) and return its row: the bundle read from
    ``bundle_dir`` if given (else generated here), ``code`` naming the library's commit (default:
    this checkout's), ``role`` "main" or "baseline" (the code the issue's target was set on)."""
    import jax

    import refine

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
    from benchmarks.diagnose import score

    DiagnoseConfig, diagnose = _diagnoser()
    case = _case(case_key)
    if bundle_dir:
        from refine.bundle import read_bundle

        truth, bundle = _truth(case), read_bundle(bundle_dir)
    else:
        from benchmarks._diagnose_oracle import _case_bundle

        truth, bundle = _case_bundle(case)
    config = DiagnoseConfig(workers=workers, **({} if linear_solver == "auto" else {"linear_solver": linear_solver}))
    compiles.update(n=0, seconds=0.0, large=0, large_seconds=0.0)  # the diagnosis's, not the bundle's
    load0 = os.getloadavg()[0]
    c0, w0 = _cpu(), time.perf_counter()
    stages = []  # [wall s, CPU s, what] at each progress line: the stages' seconds (a stage ends at its line)

    def log(msg):
        stages.append([round(time.perf_counter() - w0, 1), round(_cpu() - c0, 1), msg.split("] ", 1)[-1][:60]])

    d = diagnose(bundle, config=config, log=log)
    cpu, wall = _cpu() - c0, time.perf_counter() - w0
    s = score(truth, d)
    return {"label": label, "role": role, "code": code or _commit(), "library": str(Path(refine.__file__).parent.parent),
            "case": case_key, "points": int(bundle.observations.n_points), "bundle": bundle_digest(bundle),
            "truth": _truth_key(truth),
            "workers": workers, "linear_solver": linear_solver, "cache": bool(cache), "wall": round(wall, 1), "cpu": round(cpu, 1),
            "compiles": compiles["n"], "compile_seconds": round(compiles["seconds"], 1),
            "large_compiles": compiles["large"], "large_compile_seconds": round(compiles["large_seconds"], 1),
            "load": [round(load0, 2), round(os.getloadavg()[0], 2)], "found": s["found"], "passed": s["passed"],
            "centroid": s["centroid_error"], "ratio": s["ratio_error"], "area": s["area_error"], "gain": s["gain"],
            "chosen": d.chosen.describe(), "stages": stages}


def _median(v):
    return float(np.median(v)) if v else None


def median_target(rows: list[dict], label: str) -> dict:
    """The target judged on ``label``'s rows of this code (not a baseline's): the median wall (and
    CPU) seconds over its cases, the latest row of each case; passes with at least 3 cases under
    :data:`TARGET_WALL_S`."""
    latest = {r["case"]: r for r in rows if r["label"] == label and r.get("role", "main") == "main"}
    walls, cpus = [r["wall"] for r in latest.values()], [r["cpu"] for r in latest.values()]
    return {"target_s": TARGET_WALL_S, "label": label, "cases": sorted(latest), "median_wall_s": _median(walls),
            "median_cpu_s": _median(cpus), "loads": [latest[c]["load"] for c in sorted(latest)],
            "right_results": [latest[c]["passed"] for c in sorted(latest)],
            "pass": len(latest) >= 3 and _median(walls) < TARGET_WALL_S}


ISSUE_CODE = "df5f359"
"""The issue's code (the commit the 48 s target was set on): ``--baseline-tree`` rows of another
commit measure a change (before / after), not the issue's verdict."""


def baseline_target(rows: list[dict], label: str | None = None, issue: bool | None = None) -> dict | None:
    """"Faster than the issue's code on the same machine", judged on one label's rows of both codes
    (``--baseline-tree``: taken in one run, alternating; default the latest label with baseline
    rows): the latest row of each code per case, the cases both have on the same bundle and hidden
    effect; passes with at least 3 such cases when this code's median wall AND median CPU seconds
    are below the baseline's. ``ratio_*``: this code's median over the baseline's;
    ``median_wall_on_48s_scale_s``: 48 s times the wall ratio, this code's median on the scale of the
    issue's 48 s (which was the baseline's median there, over 120 cases)."""
    labels = [r["label"] for r in rows if r.get("role") == "baseline"
              and (issue is None or (r["code"] == ISSUE_CODE) == issue)]
    label = label or (labels[-1] if labels else None)
    if label is None:
        return None
    code = {role: {r["case"]: r for r in rows if r["label"] == label and r.get("role", "main") == role}
            for role in ("main", "baseline")}
    same = sorted(c for c in code["main"] if c in code["baseline"]
                  and code["main"][c]["bundle"] == code["baseline"][c]["bundle"]
                  and code["main"][c]["truth"] == code["baseline"][c]["truth"])
    med = {role: {x: _median([code[role][c][x] for c in same]) for x in ("wall", "cpu")} for role in code}
    ratio = {x: med["main"][x] / med["baseline"][x] if same else None for x in ("wall", "cpu")}
    return {"label": label, "cases": same, "baseline_code": sorted({code["baseline"][c]["code"] for c in same}),
            "code": sorted({code["main"][c]["code"] for c in same}),
            "median_wall_s": med["main"]["wall"], "baseline_median_wall_s": med["baseline"]["wall"],
            "median_cpu_s": med["main"]["cpu"], "baseline_median_cpu_s": med["baseline"]["cpu"],
            "ratio_wall": ratio["wall"], "ratio_cpu": ratio["cpu"],
            "median_wall_on_48s_scale_s": ratio["wall"] and TARGET_WALL_S * ratio["wall"],
            "loads": {role: [code[role][c]["load"] for c in same] for role in code},
            "right_results": {role: [code[role][c]["passed"] for c in same] for role in code},
            "pass": len(same) >= 3 and med["main"]["wall"] < med["baseline"]["wall"]
            and med["main"]["cpu"] < med["baseline"]["cpu"]}


def write(rows: list[dict], out: Path, label: str | None = None) -> dict:
    """The results JSON (rows and targets) and its plot beside it (CPU seconds and programs
    compiled per row). ``label``: whose median judges the absolute 48 s target (default: the
    latest label starting with "quiet", else the last row's)."""
    after = [r for r in rows if r["label"] != "before" and r.get("role", "main") == "main"]
    best = min(after, key=lambda r: r["wall"], default=None)
    quiet = [r["label"] for r in rows if r["label"].startswith("quiet")]
    label = label or (quiet[-1] if quiet else rows[-1]["label"] if rows else None)
    targets = {"~300-point bundles: median wall under 48 s (absolute: a wall target set on another machine)":
               median_target(rows, label),
               "300-point bundle under 48 s wall (best single row, for reference)": {
                   "target_s": TARGET_WALL_S, "best_wall_s": best and best["wall"], "its_cpu_s": best and best["cpu"],
                   "its_load": best and best["load"],
                   "pass": best is not None and best["wall"] < TARGET_WALL_S}}
    same_machine = baseline_target(rows, issue=True)
    if same_machine is not None:
        targets["~300-point bundles: faster than the issue's code on the same machine (medians, one run)"] = same_machine
    before = baseline_target(rows, issue=False)  # a change measured against the commit before it
    if before is not None:
        targets["~300-point bundles: faster than the code before the latest change (medians, one run)"] = before
    result = {"benchmark": "diagnose speed (issue 22 item 2)", "rows": rows, "targets": targets}
    out.write_text(json.dumps(result, indent=1))
    _plot(rows, out.with_suffix(".png"))
    return result


def _plot(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = [f"{r['label']} {r['code'].split()[0]}{' cache' if r.get('cache') else ''}"
             f"{' ' + r['case'].split('/')[2][:5] if r.get('role') else ''}" for r in rows]
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


def _fresh(case: str, a, role: str = "main", bundle: str | None = None) -> dict:
    """One case diagnosed in a fresh process (nothing compiled by the one before); ``role``
    "baseline": with ``PYTHONPATH`` on the baseline tree, so ``refine`` is that tree's."""
    cmd = command("diagnose_speed", "--case", case, "--label", a.label, "--workers", a.workers,
                  "--linear-solver", a.linear_solver, "--role", role)
    cmd += ["--cache", a.cache] if a.cache else []
    cmd += ["--bundle", bundle] if bundle else []
    env, cwd = environment(), None
    if role == "baseline":  # run from elsewhere, so that the working directory's refine is not the one found first
        env = environment(first=(str(Path(a.baseline_tree).resolve()),))
        cmd += ["--code", a.baseline_code or Path(a.baseline_tree).name]
    with tempfile.TemporaryDirectory() as tmp:
        cmd += ["--row-to", str(Path(tmp) / "row.json")]
        subprocess.run(cmd, env=env, check=True, cwd=tmp if role == "baseline" else cwd)
        return json.loads((Path(tmp) / "row.json").read_text())


def main(argv=None) -> int:
    argv = quick(argv, ["--cases", DEFAULT_CASES[0], "--rows", str(QUICK / "diagnose_speed_rows.jsonl"), "--out", str(QUICK / "diagnose_speed.json")])
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--case", default=None, help="one case SPACING/NOISE/CAUSE/K of benchmarks/diagnose.py "
                                                "(in this process)")
    p.add_argument("--cases", nargs="+", default=list(DEFAULT_CASES),
                   help="cases run one after another, each in a fresh process (default: %(default)s)")
    p.add_argument("--label", default="after", help="what code this row measures (e.g. before, after)")
    p.add_argument("--cache", default=None, help="JAX persistent compilation cache folder (jaxfem.compilation_cache)")
    p.add_argument("--workers", type=int, default=2, help="DiagnoseConfig.workers (the command line's default: 2)")
    p.add_argument("--linear-solver", default="auto", help="DiagnoseConfig.linear_solver")
    p.add_argument("--baseline-tree", default=None,
                   help="with --cases: a checkout of the issue's code (git archive df5f359 | tar -x -C DIR), each "
                        "case diagnosed by it and by this code on the same bundle, alternating")
    p.add_argument("--baseline-code", default=None, help="the commit of --baseline-tree (stored in its rows)")
    p.add_argument("--judge", default=None, help="the label whose median judges the absolute 48 s target "
                                                 "(default: the latest quiet* label, else this run's)")
    p.add_argument("--profile", action="store_true",
                   help="with --case: profile it instead (_diagnose_profile.py: cProfile, compilations by name, Newton "
                        "solves, CPU s per stage; results/diagnose_profile_CASE.json; no row)")
    p.add_argument("--rows", type=Path, default=OUT / "diagnose_speed_rows.jsonl")
    p.add_argument("--out", type=Path, default=OUT / "diagnose_speed.json")
    # one case in a fresh process (the runs above): where its bundle is, whose code, where its row goes
    p.add_argument("--bundle", default=None, help=argparse.SUPPRESS)
    p.add_argument("--code", default=None, help=argparse.SUPPRESS)
    p.add_argument("--role", default="main", choices=("main", "baseline"), help=argparse.SUPPRESS)
    p.add_argument("--row-to", type=Path, default=None, help=argparse.SUPPRESS)
    a = p.parse_args(argv)
    if a.baseline_tree and a.case:
        p.error("--baseline-tree runs --cases (each in a fresh process), not one --case")
    if a.baseline_tree and not (Path(a.baseline_tree) / "refine").is_dir():
        p.error(f"--baseline-tree {a.baseline_tree} holds no refine/ package: give a checkout of the issue's code")
    if a.profile:
        if not a.case:
            p.error("--profile profiles one --case")
        from benchmarks._diagnose_oracle import _case_bundle
        from benchmarks._diagnose_profile import profile_case

        DiagnoseConfig, _ = _diagnoser()
        row = profile_case(_case_bundle(_case(a.case))[1], DiagnoseConfig(workers=a.workers),
                           a.case.replace("/", "_").replace(".", "p"), OUT)
        print(json.dumps({k: row[k] for k in ("label", "cpu_s", "wall_s", "load", "compiles", "compile_s",
                                              "newton_solves", "newton_iterations", "chosen")}), flush=True)
        return 0
    if a.case:
        row = run(a.case, a.label, a.cache, a.workers, a.linear_solver, a.bundle, a.code, a.role)
        if a.row_to:  # a fresh process of the loop below: the caller keeps the row
            a.row_to.write_text(json.dumps(row))
            return 0
        print(json.dumps(row), flush=True)
        rows = [row]
    else:
        rows = []
    with tempfile.TemporaryDirectory() as folder:
        bundles = {}
        if a.baseline_tree:  # this code's bundles, written once, read by both codes
            subprocess.run([sys.executable, "-c", "import sys, json; "
                            "from benchmarks.diagnose_speed import write_bundles; from pathlib import Path; "
                            "json.dump(write_bundles(sys.argv[2:], Path(sys.argv[1])), open(Path(sys.argv[1]) / "
                            "'bundles.json', 'w'))", folder, *a.cases], check=True, env=environment())
            bundles = json.loads((Path(folder) / "bundles.json").read_text())
        for i, case in enumerate([] if a.case else a.cases):
            roles = ["main", "baseline"][:: 1 if i % 2 == 0 else -1] if a.baseline_tree else ["main"]
            for role in roles:  # alternating which code goes first, case by case
                row = _fresh(case, a, role, bundles.get(case))
                print(json.dumps(row), flush=True)
                with open(a.rows, "a") as fh:
                    fh.write(json.dumps(row) + "\n")
    if a.case:
        with open(a.rows, "a") as fh:
            fh.write(json.dumps(rows[0]) + "\n")
    result = write([json.loads(line) for line in a.rows.read_text().splitlines() if line.strip()], a.out, a.judge)
    print(json.dumps(result["targets"], indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
