"""How the global model's mesh near a hole sizes it (issue 23, seed 6's area bias; benchmarks/README.md's
diagnose3d section): the hole refitted in the global model from the TRUE hole on a kept bundle of
`diagnose3d.py` (the benchmark's data, noise included), one mesh rule per variant: the element size
along the hole's curve (``--ratios``: times its smallest radius of curvature, ``none``: h), the
elements through the bottom (``--layers``), the floor's element size (``--floor-h``) and a modulus of
the wall's own (``--wall-modulus``). Each fit is the diagnosis's global fit (free uniform
modulus, shape free) without the grid's edge constraints and without remeshing (from the truth the
morph moves a few %): what is left of the area error is the mesh's bias at that data (plus the noise
draw's, the same in every variant). Writes JSON lines to --out.

    python benchmarks/_cup_hole_mesh.py --seed 6 --bundles /tmp/cup_bundles_s22 --ratios none 0.5 --layers 0
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import time
from dataclasses import replace
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.append(str(HERE))

import numpy as np  # noqa: E402

from _timing import loadavg  # noqa: E402


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seed", type=int, default=6)
    p.add_argument("--bundles", type=Path, required=True)
    p.add_argument("--name", default="hdata0.8_s0.6_n0.005_f1-2-3-4", help="the bundle's name after cup_seed<seed>_")
    p.add_argument("--h", type=float, default=1.2)
    p.add_argument("--ratios", nargs="+", default=["none", "0.5"])
    p.add_argument("--layers", type=int, nargs="+", default=[0], help="0: bottom / h rounded")
    p.add_argument("--wall-modulus", action="store_true", help="the wall's own modulus fitted too (relative to "
                   "the uniform one)")
    p.add_argument("--floor-h", type=float, nargs="+", default=[0.0], help="the floor's element size (0: h)")
    p.add_argument("--remesh", type=int, default=0, help="remeshes after the first fit (refit; 0: none)")
    p.add_argument("--out", type=Path, default=HERE / "results" / "cup_hole_mesh.jsonl")
    args = p.parse_args()

    import jaxfem as jf
    from refine.bundle.io import read_bundle
    from refine.diagnosis.fitted import fit, refit
    from refine.solid.diagnose import SolidConfig, local_recipe
    from refine.solid.local import SolidHole, Whole
    from refine.synthetic.cup import CupGeometry, random_hole

    g = CupGeometry()
    truth = random_hole(g, args.seed)
    bundle = read_bundle(args.bundles / f"cup_seed{args.seed}_{args.name}")
    _, local, _ = local_recipe(bundle, SolidConfig(h=args.h))
    sigma = bundle.experiment.noise_std
    for layers, ratio, floor_h in [(n, q, f) for n in args.layers for q in args.ratios for f in args.floor_h]:
        q = None if ratio == "none" else float(ratio)
        recipe = replace(local, layers=layers or None, hole_ratio=q, floor_h=floor_h or None)
        whole, on = Whole.of(recipe, bundle.observations)
        guide, validate = (whole.obs.roles == "guide") & on, whole.obs.roles == "validate"
        # the truth in the cup frame: the bundle's cup is centred on the axis (offset 0 in x, y)
        e = jf.Ellipse(truth.cx - local.shape.centre[0], truth.cy - local.shape.centre[1], truth.rx, truth.ry,
                       truth.angle)
        t0, c0 = time.perf_counter(), time.process_time()
        f = fit(SolidHole(whole, e, free_modulus=True, wall_modulus=args.wall_modulus), guide, validate, sigma)
        if args.remesh:
            f = refit(f, guide, validate, sigma, max_remesh=args.remesh, element="tet10")
        s = f.shapes[0]
        area = float(np.pi * s.axes[0] * s.axes[1])
        big = int(np.argmax(s.axes))
        row = {"seed": args.seed, "h": args.h, "hole_ratio": q, "hole_h": whole.hole_h(e),
               "layers": layers or None, "floor_h": floor_h or None, "remesh": args.remesh,
               "cells": int(f.model.mesh.n_cells), "nodes": int(f.model.mesh.n_nodes),
               "area_error_pct": 100 * (area / truth.area - 1),
               "major_axis_error_pct": 100 * (s.axes[big] / max(truth.rx, truth.ry) - 1),
               "minor_axis_error_pct": 100 * (s.axes[1 - big] / min(truth.rx, truth.ry) - 1),
               "centre_error_mm": float(np.hypot(s.centre[0] - e.cx, s.centre[1] - e.cy)),
               "modulus": float(s.E), "wall_modulus": args.wall_modulus, "wall_ratio": s.wall,
               "chi2_per": float(f.chi2_fit / max(guide.sum() * 3 * whole.obs.n_frames, 1)),
               "seconds": time.perf_counter() - t0, "cpu_seconds": time.process_time() - c0,
               "max_rss_gb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6, "load": loadavg()}
        print(json.dumps(row), flush=True)
        with args.out.open("a") as fh:
            fh.write(json.dumps(row) + "\n")


if __name__ == "__main__":
    main()
