"""Where the 3D (cup holder) diagnosis's CPU seconds go (issue 23 item 5): one bundle diagnosed
by :func:`refine.solid.write.diagnose_and_write` with per-stage CPU and wall seconds, XLA
compilations counted with their seconds (``jax.monitoring``), forward solves (one per frame of an
evaluation), Newton iterations, Jacobians (tangent solves), fits and meshes built, counted per
stage; optionally under cProfile (``--profile``: the top functions by cumulative and own time).
Appends one row (load average before and after, CPU seconds, centre / area of the finding against
the bundle's true hole) to ``--out`` (JSON lines), so before / after runs alternate on one bundle.

    python benchmarks/_cup_speed.py BUNDLE --label before --out benchmarks/results/diagnose3d_speed_s24.jsonl
    python benchmarks/_cup_speed.py --out benchmarks/results/diagnose3d_speed_s24.jsonl \
        --summarise benchmarks/results/diagnose3d_speed_s24.json     # the rows with the targets, and a plot
"""

from __future__ import annotations

import argparse
import cProfile
import io
import json
import os
import pstats
import resource
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


class Counts:
    """Counters of the expensive calls, read at each stage's end."""

    def __init__(self):
        self.n = Counter()
        self.s = Counter()
        self.fits = []

    def wrap(self, owner, name: str, key: str | None = None):
        """Count calls of ``owner.name`` (and their wall seconds) under ``key``."""
        fn = getattr(owner, name)
        key = key or name

        def counted(*a, **kw):
            t = time.perf_counter()
            try:
                return fn(*a, **kw)
            finally:
                self.n[key] += 1
                self.s[key] += time.perf_counter() - t

        setattr(owner, name, counted)

    def snapshot(self) -> dict:
        return {**{k: int(v) for k, v in self.n.items()}, **{f"{k}_s": round(v, 1) for k, v in self.s.items()}}


def instrument(counts: Counts) -> None:
    import jax

    import jaxfem as jf
    import refine.diagnosis.fitted as fitted
    import numpy as np
    import refine.solid.diagnose as diagnose
    from jaxfem.solver import Solver
    from refine.model.objective import Compiled
    from refine.solid.loaded import LoadedModel

    def listen(event, duration, **kw):
        if event.endswith("backend_compile_duration"):
            counts.n["xla_compiles"] += 1
            counts.s["xla_compiles"] += duration

    jax.monitoring.register_event_duration_secs_listener(listen)
    counts.wrap(Compiled, "_solve", "evaluations")  # all frames solved at one z
    counts.wrap(Compiled, "_derivatives", "jacobians")
    counts.wrap(Compiled, "__init__", "compiled_models")
    counts.wrap(LoadedModel, "__init__", "models_built")
    counts.wrap(jf, "cup_holder", "global_meshes")
    for mod in (fitted, diagnose):
        counts.wrap(mod, "fit", "fits")
        fit = getattr(mod, "fit")

        def logged(*a, _fit=fit, **kw):
            f = _fit(*a, **kw)
            s = f.shapes[0] if f.shapes else None
            r = f.result
            counts.fits.append({"cpu_s": round(_cpu(), 1), "cells": int(f.model.mesh.n_cells), "h": f.model.h,
                                "chi2": round(float(f.chi2_fit), 1), "evaluations": getattr(r, "n_forward", None),
                                "jacobians": getattr(r, "n_gradient", None), "converged": getattr(r, "converged", None),
                                "shape": None if s is None else [*map(float, s.centre), *map(float, s.axes),
                                                                 float(s.angle), float(np.pi * s.axes[0] * s.axes[1])],
                                "E": getattr(s, "E", None)})
            print("  fit", json.dumps(counts.fits[-1]), flush=True)
            return f

        setattr(mod, "fit", logged)
    counts.wrap(diagnose, "best_start")
    counts.wrap(Solver, "__init__", "solvers_built")
    counts.wrap(Solver, "solve_for_adjoint", "frame_solves")
    counts.wrap(Solver, "tangents_at", "frame_tangents")


def truth_of(root: Path):
    """The bundle's true hole, from the seed in its name (benchmarks/diagnose3d.py's ``--bundles``)."""
    from refine.synthetic.cup import CupGeometry, random_hole
    name = root.name
    if "_sound" in name:
        return None
    seed = int(name.split("seed")[1].split("_")[0])
    return random_hole(CupGeometry(), seed)


def summarise(rows_path: Path, out: Path) -> None:
    """``out`` (JSON: the rows without their profiles, the targets judged on each row's seconds,
    with its load) and a plot beside it, from the JSON lines of the runs."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = [json.loads(line) for line in rows_path.read_text().splitlines() if line.strip()]
    for r in rows:
        r.pop("profile", None)
    targets = {r["label"]: {"points": r["points"], "cpu_s": r["cpu_s"], "load": r["load_after"][0],
                            "local_diagnosis_lt_300s": {"value": r["local_seconds"], "pass": r["local_seconds"] < 300},
                            "global_prediction_lt_60s": {"value": r["global_seconds"], "pass": r["global_seconds"] < 60}}
               for r in rows}
    out.write_text(json.dumps({"rows": rows, "targets": targets}, indent=1, default=str), encoding="utf-8")
    fig, ax = plt.subplots(figsize=(9, 4))
    names = [f"{r['label']}\n{r['points']} pts, load {r['load_after'][0]:.1f}" for r in rows]
    ax.bar(names, [r["cpu_s"] for r in rows], label="CPU s (whole run)")
    ax.bar(names, [r["local_seconds"] for r in rows], alpha=0.5, label="local diagnosis wall s")
    ax.bar(names, [r["global_seconds"] for r in rows], alpha=0.8, label="global prediction wall s")
    ax.axhline(300, color="C1", ls="--")
    ax.axhline(60, color="C2", ls="--")
    ax.tick_params(axis="x", labelsize=7)
    ax.set_ylabel("seconds")
    ax.legend()
    fig.tight_layout()
    fig.savefig(out.with_suffix(".png"), dpi=100)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("bundle", type=Path, nargs="?")
    p.add_argument("--summarise", type=Path, default=None, help="write this JSON (and its plot) from --out's rows "
                   "and stop")
    p.add_argument("--label", default="run")
    p.add_argument("--out", type=Path, default=HERE / "results" / "diagnose3d_speed_s24.jsonl")
    p.add_argument("--profile", action="store_true", help="under cProfile (slower); top functions in the row")
    p.add_argument("--model-h", type=float, default=None)
    args = p.parse_args()
    if args.summarise:
        return summarise(args.out, args.summarise)

    import numpy as np

    from refine.bundle.io import read_bundle
    from refine.solid.diagnose import SolidConfig
    from refine.solid.write import diagnose_and_write
    from refine.synthetic.cup import CupGeometry

    counts = Counts()
    instrument(counts)
    stages, c0, w0 = [], _cpu(), time.perf_counter()

    def log(msg):
        stages.append({"cpu_s": round(_cpu() - c0, 1), "wall_s": round(time.perf_counter() - w0, 1),
                       **counts.snapshot(), "line": str(msg)[:140]})
        print(json.dumps(stages[-1]), flush=True)

    import refine.solid.write as write
    quiet_log = log
    orig = write.diagnose_solid
    write.diagnose_solid = lambda b, cfg, log=None: orig(b, cfg, log=quiet_log)
    bundle = read_bundle(args.bundle)
    load0 = os.getloadavg()
    prof = cProfile.Profile() if args.profile else None
    if prof:
        prof.enable()
    with tempfile.TemporaryDirectory() as tmp:
        d, rep = diagnose_and_write(bundle, Path(tmp) / "out", SolidConfig(h=args.model_h), quiet=True)
    if prof:
        prof.disable()
    log("end")
    row = {"label": args.label, "bundle": str(args.bundle), "points": int(len(d.local.obs.ids)), "h": d.local.h,
           "cpu_s": round(_cpu() - c0, 1), "wall_s": round(time.perf_counter() - w0, 1),
           "load_before": load0, "load_after": os.getloadavg(), "seconds": rep["seconds"],
           "local_seconds": sum(rep["seconds"].values()),
           "global_seconds": max(v["seconds"] for v in rep["global"].values() if isinstance(v, dict)),
           "max_rss_gb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6,
           "cause": rep["cause"], "stages": stages, "counts": counts.snapshot(), "fits": counts.fits, "time": time.strftime("%H:%M:%S")}
    truth = truth_of(args.bundle)
    if truth is not None and rep["findings"]:
        f, g = rep["findings"][0], CupGeometry()
        row["centre_error_pct"] = 100 * np.hypot(f["centroid"][0] - truth.cx, f["centroid"][1] - truth.cy) / g.diameter
        row["area_error_pct"] = 100 * (f["area"] / truth.area - 1)
        row["area_std_pct"] = None if not f.get("std") else 100 * f["std"]["area"] / truth.area
        if f.get("discretisation"):
            row["area_disc_pct"] = 100 * f["discretisation"]["area"] / truth.area
        row["modulus"] = f.get("E")
        row["finding"] = {k: f[k] for k in ("centroid", "axes", "angle", "area")}
    if prof:
        s = io.StringIO()
        st = pstats.Stats(prof, stream=s)
        top = []
        for key in ("cumulative", "tottime"):
            st.sort_stats(key)
            for func in st.fcn_list[:35]:
                cc, nc, tt, ct, _ = st.stats[func]
                top.append({"by": key, "function": f"{Path(func[0]).name}:{func[1]}({func[2]})", "calls": nc,
                            "own_s": round(tt, 2), "cumulative_s": round(ct, 2)})
        row["profile"] = top
        prof.dump_stats(str(args.out.with_suffix(f".{args.label}.prof")))
    print(json.dumps({k: v for k, v in row.items() if k not in ("stages", "profile")}), flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with args.out.open("a") as fh:
        fh.write(json.dumps(row, default=str) + "\n")


if __name__ == "__main__":
    main()
