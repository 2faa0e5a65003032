"""The misfit along the size-ratio valley of a stiff circle of ``error_coverage.py``.

    python benchmarks/error_coverage_valley.py --seeds 9108 9412 9444

A small very stiff region and a larger less stiff one move the tracked points nearly alike.
For each case (its bundle and start as ``error_coverage.py`` makes them: 10 mm grid, the last
frame), the region is fitted as the benchmark fits it (linear triangles, from its start, then
the restarts of :data:`refine.diagnosis.restarts.RESTARTS`), then held as circles at the fitted
centre whose radius is the fitted one's (of equal area) times ``--scales``, each with its ratio
alone refitted: the misfit's profile along the valley (chi2 on the fitting points). The truth's
circle with its ratio refitted, and the full fit started from the truth, are scored beside it.
Rows to ``results/error_coverage_valley.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np
from error_coverage import _code_version, started, true_quantities, truth_of

OUT = Path(__file__).parent / "results"


def scan(seed: int, scales, noise: float, spacing: float, kind: str = "stiffer-region") -> dict:
    """One case's valley: the fitted region, the profile along ``scales`` and the truth's fits."""
    from refine.diagnosis.fitted import fit
    from refine.diagnosis.regions import regions_hypothesis
    from refine.diagnosis.restarts import RESTARTS, best_of_restarts
    from refine.diagnosis.shapes import RegionShape
    from refine.model.measured import MeasuredModel
    from refine.synthetic.sheet import synthetic_bundle

    t0 = time.perf_counter()
    q = true_quantities(truth_of(kind, seed))
    bundle = synthetic_bundle(truth_of(kind, seed), seed=seed, spacing=spacing, noise=noise, fractions=(1.0,))
    start = started(q, kind, spacing, np.random.default_rng(seed + 1))
    obs = bundle.observations
    model = MeasuredModel(bundle.experiment, obs)
    guide, hold = obs.mask("guide"), obs.mask("validate")
    sign = [1 if start.ratio > 1 else -1]
    first = fit(regions_hypothesis(model, [start], sign), guide, hold, noise)
    f = best_of_restarts(first, [start], guide, hold, RESTARTS)
    s = f.shapes[0]
    r = float(np.sqrt(s.axes[0] * s.axes[1]))
    row = {"seed": seed, "kind": kind, "truth": q.tolist(), "first": first.describe(), "fitted": f.describe(),
           "fitted_chi2": f.chi2_fit, "fitted_radius": r, "fitted_ratio": s.ratio, "profile": []}
    for c in scales:
        circle = RegionShape(s.centre, (c * r, c * r), 0.0, s.kind, s.ratio / c**2)
        g = fit(regions_hypothesis(model, [circle], sign, geometry=False), guide, hold, noise)
        row["profile"].append({"scale": c, "radius": c * r, "ratio": g.shapes[0].ratio, "chi2": g.chi2_fit})
        print(f"{seed} scale {c:.2f} radius {c * r:.2f} ratio {g.shapes[0].ratio:.2f} chi2 {g.chi2_fit:.1f}", flush=True)
    true_circle = RegionShape(tuple(q[:2]), tuple(q[2:4]), float(q[4]), s.kind, float(q[6]))
    held = fit(regions_hypothesis(model, [true_circle], sign, geometry=False), guide, hold, noise)
    free = fit(regions_hypothesis(model, [true_circle], sign), guide, hold, noise)
    row.update(truth_shape_ratio_refitted={"ratio": held.shapes[0].ratio, "chi2": held.chi2_fit},
               from_truth={"fitted": free.describe(), "chi2": free.chi2_fit},
               seconds=time.perf_counter() - t0, load_average=[round(x, 2) for x in os.getloadavg()],
               code=_code_version())
    print(f"{seed}: fitted {f.describe()}; truth's circle, ratio refitted: {held.shapes[0].ratio:.2f} "
          f"chi2 {held.chi2_fit:.1f}; from the truth: {free.describe()}", flush=True)
    return row


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, nargs="+", default=[9108, 9412, 9444])
    p.add_argument("--scales", type=float, nargs="+", default=[0.8, 0.9, 1.0, 1.1, 1.2, 1.3])
    p.add_argument("--noise", type=float, default=0.02)
    p.add_argument("--spacing", type=float, default=10.0)
    p.add_argument("--out", type=Path, default=OUT / "error_coverage_valley.json")
    args = p.parse_args()
    rows = [scan(seed, args.scales, args.noise, args.spacing) for seed in args.seeds]
    OUT.mkdir(exist_ok=True)
    args.out.write_text(json.dumps({"rows": rows}, indent=1))


if __name__ == "__main__":
    main()
