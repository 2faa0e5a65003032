"""Diagnosis benchmark: rates of right causes and false alarms, localisation and ratio errors,
gain and seconds, over random hidden cases per cause, at two grid densities and two noise levels.

    python benchmarks/diagnose.py                 # 20 cases per cause and setting (long)
    python benchmarks/diagnose.py --cases 3       # a quick look

Writes benchmarks/results/diagnose.json (and diagnose.png). Each case draws its hidden effect
(location, size, ratio) under its own seed; data come from a finer quadratic mesh of a larger
sheet, with noise; the inversion uses linear triangles on the tracked region.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from refine.diagnose import diagnose
from refine.synthetic import CAUSES, random_truth, synthetic_bundle

DIAGONAL = float(np.hypot(100.0, 60.0))
OUT = Path(__file__).parent / "results"


def score(truth, d) -> dict:
    """Right cause, centroid and ratio errors of one case."""
    found = d.findings
    want = sorted(truth.causes)
    row = {"found": [f["cause"] for f in found], "truth": want, "right_cause": sorted(f["cause"] for f in found) == want,
           "false_alarm": bool(found) and not want, "gain": d.errors["gain"], "seconds": d.seconds,
           "centroid_error": [], "ratio_error": [], "area_error": []}
    shapes = [(inc.shape, inc.ratio) for inc in truth.inclusions] + [(h, 0.0) for h in truth.holes]
    for shape, ratio in shapes:
        cands = [f for f in found if f["region"]]
        if not cands:
            continue
        f = min(cands, key=lambda f: np.hypot(f["region"]["centroid"][0] - shape.cx, f["region"]["centroid"][1] - shape.cy))
        c = f["region"]["centroid"]
        row["centroid_error"].append(float(np.hypot(c[0] - shape.cx, c[1] - shape.cy) / DIAGONAL))
        if ratio > 0:
            row["ratio_error"].append(float(abs(f["relative_elasticity"] / ratio - 1)))
        else:
            row["area_error"].append(float(abs(f["region"]["area"] / shape.area - 1)))
    return row


def summarise(rows) -> dict:
    def med(key):
        v = [x for r in rows for x in r[key]]
        return float(np.median(v)) if v else None

    gains = [r["gain"] for r in rows if r["gain"]]
    return {"cases": len(rows), "right_cause_rate": float(np.mean([r["right_cause"] for r in rows])),
            "false_alarm_rate": float(np.mean([r["false_alarm"] for r in rows])),
            "median_centroid_error_of_diagonal": med("centroid_error"), "median_ratio_error": med("ratio_error"),
            "median_hole_area_error": med("area_error"), "median_gain": float(np.median(gains)) if gains else None,
            "median_seconds": float(np.median([r["seconds"] for r in rows]))}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cases", type=int, default=20)
    ap.add_argument("--spacings", type=float, nargs="+", default=[10.0, 5.0])
    ap.add_argument("--noises", type=float, nargs="+", default=[0.02, 0.05])
    ap.add_argument("--causes", nargs="+", default=list(CAUSES))
    args = ap.parse_args()
    OUT.mkdir(exist_ok=True)
    results = {"settings": vars(args), "groups": []}
    for spacing in args.spacings:
        for noise in args.noises:
            for cause in args.causes:
                rows = []
                for k in range(args.cases):
                    seed = 1000 * int(spacing) + 100 * CAUSES.index(cause) + k
                    truth = random_truth(np.random.default_rng(seed), cause)
                    t0 = time.perf_counter()
                    bundle = synthetic_bundle(truth, seed=seed, spacing=spacing, noise=noise)
                    d = diagnose(bundle, log=lambda m: None)
                    row = score(truth, d)
                    row["seed"], row["data_seconds"] = seed, time.perf_counter() - t0 - d.seconds
                    rows.append(row)
                    print(f"spacing {spacing} noise {noise} {cause:15s} seed {seed}: found {row['found']} "
                          f"gain {row['gain'] or 0:.2f} {row['seconds']:.0f} s", flush=True)
                group = {"spacing": spacing, "noise": noise, "cause": cause, **summarise(rows), "rows": rows}
                results["groups"].append(group)
                (OUT / "diagnose.json").write_text(json.dumps(results, indent=1))
    _plot(results)


def _plot(results):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    groups = results["groups"]
    fig, ax = plt.subplots(figsize=(9, 4))
    labels = [f"{g['cause']}\n{g['spacing']:.0f}mm/{g['noise']}" for g in groups]
    x = np.arange(len(groups))
    ax.bar(x - 0.2, [g["right_cause_rate"] for g in groups], 0.4, label="right cause")
    ax.bar(x + 0.2, [g["false_alarm_rate"] for g in groups], 0.4, label="false alarm")
    ax.set_xticks(x, labels, fontsize=6, rotation=90)
    ax.legend()
    fig.savefig(OUT / "diagnose.png", dpi=110, bbox_inches="tight")


if __name__ == "__main__":
    main()
