"""Where the cup holder's hole area error comes from (issue 23 item 4; benchmarks/README.md's
diagnose3d section, session 24): the diagnosis's fitted hole (read from a ``diagnose3d.py``
result) refitted in the global model at several element sizes, each fit the diagnosis's
discretisation refit (:func:`refine.diagnosis.uncertainty.discretisation_bias`: the same
hypothesis, free uniform modulus, the grid's edge constraints, no remesh, started at the fitted
hole and modulus), on the kept bundle of the same data.

Per element size ``h`` it writes the fitted ellipse's area error, the area the model's mesh
actually cuts (its polygon through the hole's curve nodes; mid-edge nodes straight) against the
drawn ellipse, the modulus and the misfit. With the fit at the diagnosis's h (1.2) and at
sqrt(2) h, the SIGNED Richardson extrapolation (order 2) is ``A_fine + (A_fine - A_coarse)``;
a third, finer h checks the trend. ``--polygon-only``: only the polygons (no fit; seconds);
``--summary rows.jsonl --out table.json``: the extrapolations per seed from such rows.

    python benchmarks/_cup_area.py --seed 2 --bundles /tmp/cup_bundles_s24 \
        --result benchmarks/results/diagnose3d_fine_s23_seed2.json --hs 1.2 1.697
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.append(str(HERE))

import numpy as np  # noqa: E402

from _timing import loadavg  # noqa: E402


def cut_fraction(g, ellipse, h: float, hole_h: float | None = None) -> float:
    """The area of the hole a floor meshed at ``h`` (``hole_h`` along the hole) cuts for ``ellipse``
    (the polygon through its curve's nodes, shoelace; the same plan as the cup's), over the
    ellipse's area."""
    import jaxfem as jf
    from jaxfem.mesher import domain
    from jaxfem.shapes import curve_nodes

    m = domain(jf.Ellipse(0.0, 0.0, g.r_in, g.r_in), h, holes=(ellipse,), curve_h=[hole_h])
    x = m.nodes[curve_nodes(m, ellipse)]
    return 0.5 * abs(x[:, 0] @ np.roll(x[:, 1], -1) - x[:, 1] @ np.roll(x[:, 0], -1)) / ellipse.area


def summary(rows: list[dict], h: float = 1.2, factor: float = np.sqrt(2.0)) -> list[dict]:
    """Per seed (rows of this script at ``h`` and ``factor`` h, the last of each): the area errors
    (% of the true ellipse) of the fit, of the ellipse's signed Richardson extrapolation
    (``A_fine + (A_fine - A_coarse)``, order 2) and of the cut area's (the polygon's share times the
    ellipse, against the data's cut), the modulus extrapolated the same way."""
    out = []
    for seed in sorted({r["seed"] for r in rows}):
        at = {round(r["h"], 3): r for r in rows if r["seed"] == seed and "area_error_pct" in r}
        f, c = at.get(round(h, 3)), at.get(round(factor * h, 3))
        if f is None or c is None:
            continue
        k = 1.0 / (factor**2 - 1.0)
        ell = f["area_error_pct"] + k * (f["area_error_pct"] - c["area_error_pct"])
        cut = f["cut_area_error_pct"] + k * (f["cut_area_error_pct"] - c["cut_area_error_pct"])
        row = {"seed": seed, "fine_pct": f["area_error_pct"], "coarse_pct": c["area_error_pct"],
               "signed_change_pct": c["area_error_pct"] - f["area_error_pct"],
               "reported_pct": f["reported_area_error_pct"], "reported_disc_pct": f["reported_disc_pct"],
               "ellipse_richardson_pct": ell, "cut_fine_pct": f["cut_area_error_pct"],
               "cut_coarse_pct": c["cut_area_error_pct"], "cut_richardson_vs_data_cut_pct": cut,
               "cut_richardson_pct": 100 * ((1 + cut / 100) * f["data_cut_fraction"] - 1),
               "modulus_fine": f["modulus"], "modulus_coarse": c["modulus"],
               "modulus_richardson": f["modulus"] + k * (f["modulus"] - c["modulus"])}
        finer = next((r for k_, r in at.items() if abs(k_ - h / factor) < 0.01), None)  # 0.85 for 0.8485
        if finer is not None:  # order 2: the finer fit's cut area halfway between the fine one and the limit
            row.update({"finer_pct": finer["area_error_pct"], "cut_finer_pct": finer["cut_area_error_pct"],
                        "cut_finer_predicted_pct": 0.5 * (cut + f["cut_area_error_pct"]),
                        "modulus_finer": finer["modulus"]})
        out.append(row)
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--summary", type=Path, help="only summarise these rows (JSONL) into --out (JSON)")
    p.add_argument("--seed", type=int)
    p.add_argument("--bundles", type=Path)
    p.add_argument("--result", type=Path, help="the diagnose3d.py JSON of this seed's diagnosis")
    p.add_argument("--name", default="hdata0.8_s0.6_n0.005_f1-2-3-4", help="the bundle's name after cup_seed<seed>_")
    p.add_argument("--hs", type=float, nargs="+", default=[1.2, 1.2 * np.sqrt(2)])
    p.add_argument("--model-h", type=float, default=1.2, help="the diagnosis's element size")
    p.add_argument("--h-data", type=float, default=0.8, help="the data's element size (its polygon's share)")
    p.add_argument("--layers", type=int, default=None, help="elements through the bottom (default: bottom / h rounded)")
    p.add_argument("--polygon-only", action="store_true")
    p.add_argument("--out", type=Path, default=HERE / "results" / "cup_area_s24.jsonl")
    args = p.parse_args()
    if args.summary:
        rows = [json.loads(line) for line in args.summary.read_text().splitlines() if line.strip()]
        table = summary(rows)
        args.out.write_text(json.dumps(table, indent=1) + "\n")
        for r in table:
            print(" ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in r.items()))
        return
    if args.seed is None or args.bundles is None or args.result is None:
        p.error("--seed, --bundles and --result are needed without --summary")

    import jaxfem as jf
    from refine.bundle.io import read_bundle
    from refine.diagnosis.fitted import fit
    from refine.solid.diagnose import SolidConfig, grid_edge, local_recipe
    from refine.solid.local import SolidHole, Whole
    from refine.synthetic.cup import CupGeometry, data_hole_h, random_hole
    from refine.diagnosis.shapes import Hole

    g = CupGeometry()
    truth = random_hole(g, args.seed)
    row0 = next(r for r in json.loads(args.result.read_text())["rows"] if r["seed"] == args.seed)
    found = row0["report"]["findings"][0]
    bundle = read_bundle(args.bundles / f"cup_seed{args.seed}_{args.name}")
    cfg = SolidConfig(h=args.model_h)
    _, local, _ = local_recipe(bundle, cfg)
    if args.layers is not None:
        from dataclasses import replace
        local = replace(local, layers=args.layers)
    c = np.asarray(found["centroid"][:2]) - np.asarray(local.shape.offset[:2])
    e = jf.Ellipse(*c, *found["axes"], found["angle"])
    true_e = jf.Ellipse(truth.cx - local.shape.centre[0], truth.cy - local.shape.centre[1], truth.rx, truth.ry,
                        truth.angle)
    data_frac = cut_fraction(g, true_e, args.h_data, data_hole_h(true_e, args.h_data))
    base = {"seed": args.seed, "bundle": args.name, "result": args.result.name, "reported_area_error_pct": row0["area_error_pct"],
            "reported_disc_pct": row0.get("area_disc_pct"), "reported_E": found.get("E"),
            "data_cut_fraction": data_frac}
    if args.polygon_only:
        for h in args.hs:
            row = {**base, "h": h, "fitted_cut_fraction": cut_fraction(g, e, h),
                   "true_cut_fraction": cut_fraction(g, true_e, h)}
            print(json.dumps(row), flush=True)
            with args.out.open("a") as fh:
                fh.write(json.dumps(row) + "\n")
        return
    sigma = bundle.experiment.noise_std
    whole, on = Whole.of(local, bundle.observations)
    guide, validate = (whole.obs.roles == "guide") & on, whole.obs.roles == "validate"
    edge = grid_edge(local, Hole(tuple(e.params[:2]), tuple(e.params[2:4]), float(e.params[4])), cfg)
    for h in args.hs:
        t0, c0 = time.perf_counter(), time.process_time()
        hyp = SolidHole(whole, e, free_modulus=True, edge=edge, E_start=found.get("E"),
                        h=None if abs(h - args.model_h) < 1e-9 else h)
        f = fit(hyp, guide, validate, sigma)
        s = f.shapes[0]
        area = float(np.pi * s.axes[0] * s.axes[1])
        fe = jf.Ellipse(*s.centre, *s.axes, s.angle)
        frac = cut_fraction(g, fe, h)
        row = {**base, "h": h, "layers": args.layers, "cells": int(f.model.mesh.n_cells), "nodes": int(f.model.mesh.n_nodes),
               "edge_missing": None if edge is None else int(len(edge.missing)),
               "area": area, "area_error_pct": 100 * (area / truth.area - 1),
               "cut_fraction": frac, "cut_area_error_pct": 100 * (area * frac / (truth.area * data_frac) - 1),
               "true_cut_fraction": cut_fraction(g, true_e, h),
               "centre_error_mm": float(np.hypot(s.centre[0] - true_e.cx, s.centre[1] - true_e.cy)),
               "axes": list(map(float, s.axes)), "ellipse": fe.params.tolist(), "modulus": float(s.E),
               "chi2_per": float(f.chi2_fit / max(guide.sum() * 3 * whole.obs.n_frames, 1)),
               "seconds": time.perf_counter() - t0, "cpu_seconds": time.process_time() - c0,
               "max_rss_gb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6, "load": loadavg()}
        print(json.dumps(row), flush=True)
        with args.out.open("a") as fh:
            fh.write(json.dumps(row) + "\n")


if __name__ == "__main__":
    main()
