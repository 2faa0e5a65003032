"""Batch diagnosis scaling: bundles per minute of refine.batch.diagnose_many on 1 and 2 workers.

Batch diagnosis scaling: throughput (bundles per minute) of ``refine.batch.diagnose_many`` on 1 and
2 local workers against one process diagnosing the same bundles one after another, the overhead per
bundle and the parallel efficiency.

    python -m benchmarks batch                     # 4 small bundles, 1 and 2 workers
    python -m benchmarks batch --bundles 8 --workers 1 2 4 --note "idle 16-core machine"

The bundles are synthetic sheets with nothing hidden (cause "none"), tracked on a 10 mm grid over
a 40 x 30 mm region, one frame: small, so that the fixed costs (worker start, JAX import) weigh as
much as they ever will. Each mode starts from a fresh process or cluster and is timed end to end:
the one-process run is a spawned interpreter with the workers' environment (one XLA/BLAS thread)
that runs :func:`refine.batch.diagnose_one` on each bundle in turn; the batch runs are
``diagnose_many(..., workers=N, threads_per_worker=1, figures=False)``, cluster start included.
Every mode's report.json must be the same (the ``same_reports`` target).

Writes benchmarks/results/batch.json (with a ``targets`` section) and batch.png.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import subprocess
import time
from pathlib import Path

import numpy as np

from benchmarks._subprocess import command, environment
from benchmarks._cli import quick

OUT = Path(__file__).parent / "results"
EFFICIENCY_MIN = 0.7  # on 2 workers, against the one-process run
OVERHEAD_MAX = 0.10  # batch on 1 worker: extra wall time per bundle, as a share of the one-process time


def make_bundles(work: Path, n: int) -> list[Path]:
    """``n`` small synthetic bundles (seeds 1..n) in ``work/bundles``, made once and reused."""
    from refine.bundle import write_bundle
    from refine.demo_data import random_truth, synthetic_bundle

    paths = []
    for seed in range(1, n + 1):
        p = work / "bundles" / f"sheet-{seed:02d}"
        if not (p / "displacements.csv").is_file():
            truth = random_truth(np.random.default_rng(seed), "none")
            write_bundle(p, synthetic_bundle(truth, seed=seed, roi=(20.0, 10.0, 60.0, 40.0),
                                             sheet=(0.0, 0.0, 80.0, 50.0), spacing=10.0, fractions=(1.0,), h=8.0,
                                             name=p.name))
        paths.append(p)
    return paths


def one_process(paths: list[Path], out: Path) -> dict:
    """Diagnose ``paths`` one after another in a fresh interpreter with one worker's environment."""
    from refine.batch import worker_env

    env = environment(**worker_env(1))
    t0 = time.perf_counter()
    subprocess.run(command("batch", "--one-process", out, *paths), env=env, check=True)
    wall = time.perf_counter() - t0
    rows = [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]
    return {"wall_s": wall, "task_s": [r["seconds"] for r in rows]}


def _one_process_main(out: Path, paths: list[str]) -> None:
    from refine.batch import diagnose_one
    from refine.batch.table import append_row
    from refine.diagnosis import DiagnoseConfig

    out.mkdir(parents=True, exist_ok=True)
    for p in paths:
        append_row(out / "results.jsonl", diagnose_one(p, str(out / Path(p).name), DiagnoseConfig(workers=1), False))


def batch(paths: list[Path], out: Path, workers: int) -> dict:
    """``diagnose_many`` on a fresh local cluster of ``workers`` one-thread workers, timed end to end."""
    from refine.batch import diagnose_many
    from refine.diagnosis import DiagnoseConfig

    t0 = time.perf_counter()
    table = diagnose_many(paths, out, config=DiagnoseConfig(workers=1), workers=workers, threads_per_worker=1,
                          progress=False, figures=False)
    wall = time.perf_counter() - t0
    assert not table.failed, table.summary()
    return {"wall_s": wall, "task_s": [r["seconds"] for r in table.rows],
            "workers_used": len({r["worker"] for r in table.rows})}


def _report(out: Path, name: str) -> dict:
    r = json.loads((out / name / "report.json").read_text())
    return {k: v for k, v in r.items() if k != "seconds"}


def main(argv=None) -> int:
    argv = quick(argv, ["--bundles", "2", "--workers", "1", "--note", "--quick smoke run"])
    ap = argparse.ArgumentParser()
    ap.add_argument("--bundles", type=int, default=4, help="number of small bundles")
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2], help="local worker counts to time")
    ap.add_argument("--work", default="/tmp/nonrigid-batch-benchmark", help="scratch directory")
    ap.add_argument("--note", default="", help="what the reader must know about this run (stored in the JSON)")
    ap.add_argument("--one-process", nargs="+", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.one_process:
        return _one_process_main(Path(args.one_process[0]), args.one_process[1:])
    work = Path(args.work)
    paths = make_bundles(work, args.bundles)
    for d in ["one-process"] + [f"workers-{n}" for n in args.workers]:
        shutil.rmtree(work / d, ignore_errors=True)
    modes = {}
    load = {"before": [round(x, 2) for x in os.getloadavg()]}
    modes["one-process"] = one_process(paths, work / "one-process")
    load["after one-process"] = [round(x, 2) for x in os.getloadavg()]
    for n in args.workers:
        modes[f"workers-{n}"] = {"workers": n, **batch(paths, work / f"workers-{n}", n)}
        load[f"after workers-{n}"] = [round(x, 2) for x in os.getloadavg()]
        print(f"{n} workers: {modes[f'workers-{n}']['wall_s']:.1f} s", flush=True)
    n_b = len(paths)
    for m in modes.values():
        m["bundles_per_minute"] = 60.0 * n_b / m["wall_s"]
        m["mean_task_s"] = float(np.mean(m["task_s"]))
    seq = modes["one-process"]
    results = {"bundles": n_b, "modes": modes,
               "overhead_per_bundle_s": (modes["workers-1"]["wall_s"] - seq["wall_s"]) / n_b if "workers-1" in modes
               else None}
    for n in args.workers:
        m = modes[f"workers-{n}"]
        m["speedup"] = seq["wall_s"] / m["wall_s"]
        m["efficiency"] = m["speedup"] / n
        if "workers-1" in modes:
            m["efficiency_vs_1_worker"] = modes["workers-1"]["wall_s"] / (n * m["wall_s"])
    same = all(_report(work / "one-process", p.name) == _report(work / f"workers-{n}", p.name)
               for p in paths for n in args.workers)
    targets = {"same_reports": {"target": "every mode's report.json equal (seconds aside)", "pass": same}}
    if "workers-2" in modes:
        e = modes["workers-2"]["efficiency"]
        targets["efficiency_2_workers"] = {"target": f">= {EFFICIENCY_MIN}", "value": round(e, 3),
                                           "pass": e >= EFFICIENCY_MIN}
    if results["overhead_per_bundle_s"] is not None:
        share = results["overhead_per_bundle_s"] / (seq["wall_s"] / n_b)
        targets["overhead_1_worker"] = {"target": f"<= {OVERHEAD_MAX:.0%} of a bundle's one-process time",
                                        "value": round(share, 3), "pass": share <= OVERHEAD_MAX}
    out = {"machine": {"platform": platform.platform(), "cpu_count": os.cpu_count(),
                       "cores_available": len(os.sched_getaffinity(0)), "load_average": load},
           "settings": {k: v for k, v in vars(args).items() if k != "one_process"},
           "results": results, "targets": targets,
           "notes": args.note or ("shared 2-core machine under heavy load from other sessions (see load_average): "
                                  "wall times and efficiency reflect the share of the cores the runs got, not the "
                                  "code alone")}
    OUT.mkdir(exist_ok=True)
    (OUT / "batch.json").write_text(json.dumps(out, indent=2))
    _plot(modes, OUT / "batch.png")
    print(json.dumps({"results": results, "targets": targets}, indent=2))
    return 0


def _plot(modes: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(modes)
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4))
    a.bar(names, [modes[k]["bundles_per_minute"] for k in names], color="tab:blue")
    a.set_ylabel("bundles per minute (end to end)")
    a.set_title("throughput")
    b.boxplot([modes[k]["task_s"] for k in names], tick_labels=names)
    b.set_ylabel("seconds per bundle on its worker")
    b.set_title("time per bundle")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    raise SystemExit(main())
