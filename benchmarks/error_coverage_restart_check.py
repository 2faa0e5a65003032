"""Where a region fit of ``error_coverage.py`` settles from other restarts (seed 9108 by default).

    python benchmarks/error_coverage_restart_check.py --kind stiffer-region --seed 9108

The case's bundle and start as ``error_coverage.py`` makes them (10 mm grid, the last frame);
the first fit from the start, then fits on linear triangles at the first fit's centre from: the
restarts of :data:`refine.diagnosis.restarts.RESTARTS` (``recentred``, ``round``: both keep the
fitted ratio; since 26 Nov also ``larger`` and ``smaller`` along the size-ratio valley), the start's outline at the start's ratio, a circle of the fitted area at half the
fitted ratio, a circle of 1.15 times its radius at half the ratio (the other side of the trade
between size and ratio), and the truth. Misfits (chi2 on the fitting points) and shapes to
``results/error_coverage_restart_check.json``; ``targets``: whether a restart of
``RESTARTS`` reaches within 2 of the misfit from the truth.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from error_coverage import _code_version, started, true_quantities, truth_of

OUT = Path(__file__).parent / "results"


def main():
    from refine.diagnosis.fitted import fit
    from refine.diagnosis.regions import regions_hypothesis
    from refine.diagnosis.restarts import RESTARTS, restart_shapes
    from refine.diagnosis.shapes import RegionShape
    from refine.model.measured import MeasuredModel
    from refine.synthetic.sheet import synthetic_bundle

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--kind", default="stiffer-region", choices=("stiffer-region", "softer-region"))
    p.add_argument("--seed", type=int, default=9108)
    p.add_argument("--noise", type=float, default=0.02)
    p.add_argument("--spacing", type=float, default=10.0)
    args = p.parse_args()
    t0 = time.perf_counter()
    truth = truth_of(args.kind, args.seed)
    q = true_quantities(truth)
    bundle = synthetic_bundle(truth, seed=args.seed, spacing=args.spacing, noise=args.noise, fractions=(1.0,))
    start = started(q, args.kind, args.spacing, np.random.default_rng(args.seed + 1))
    obs = bundle.observations
    model = MeasuredModel(bundle.experiment, obs)
    guide, hold = obs.mask("guide"), obs.mask("validate")
    first = fit(regions_hypothesis(model, [start], [1 if start.ratio > 1 else -1]), guide, hold, args.noise)
    s = first.shapes[0]
    r = float(np.sqrt(s.axes[0] * s.axes[1]))
    starts = {kind: shapes[0] for kind in RESTARTS if (shapes := restart_shapes(kind, [start], [s])) is not None}
    starts.update({"start_outline_and_ratio_at_fitted_centre": replace(start, centre=s.centre),
                   "round_fitted_area_half_ratio": RegionShape(s.centre, (r, r), 0.0, s.kind, s.ratio / 2),
                   "round_1.15_radius_half_ratio": RegionShape(s.centre, (1.15 * r, 1.15 * r), 0.0, s.kind, s.ratio / 2),
                   "truth": RegionShape(tuple(q[:2]), tuple(q[2:4]), float(q[4]), s.kind, float(q[6]))})
    fits = {"first": {"chi2": first.chi2_fit, "fitted": first.describe()}}
    for name, shape in starts.items():
        g = fit(first.hypothesis.at([shape], "tri3"), guide, hold, args.noise)
        fits[name] = {"chi2": g.chi2_fit, "fitted": g.describe()}
        print(f"{name}: {g.describe()}", flush=True)
    best = min(fits[k]["chi2"] for k in ("first", *RESTARTS) if k in fits)
    out = {"kind": args.kind, "seed": args.seed, "truth": q.tolist(), "fits": fits,
           "targets": {"restarts_reach_the_truth_s_misfit": {"value": best, "truth": fits["truth"]["chi2"],
                                                             "pass": bool(best <= fits["truth"]["chi2"] + 2)}},
           "seconds": time.perf_counter() - t0, "load_average": [round(x, 2) for x in os.getloadavg()],
           "code": _code_version()}
    OUT.mkdir(exist_ok=True)
    (OUT / "error_coverage_restart_check.json").write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
