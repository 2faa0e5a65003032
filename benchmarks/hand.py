"""The articulated hand of the paper's Sec. 5 (jaxfem.hand): model size, seconds per frame, and the
maximum skin strain of its three motions with and without a scar on the wrist.

    python benchmarks/hand.py                 # paper-size hand, 3 motions x (no, small, large scar); larger hand timed
    python benchmarks/hand.py --quick         # 3 frames per motion, no larger hand
    python benchmarks/hand.py --paper-only    # the paper-size hand's motions only; the larger hand's and the
                                              # finer mesh's entries are carried from the last hand.json (marked)
    python benchmarks/hand.py --fine-only     # only the finer mesh's wrist motions, into the last hand.json
    python benchmarks/hand.py --series out/hand   # also the ParaView series of every run

Sizes: the paper-size hand (jaxfem.hand.PAPER at h = 24 mm: one finger block, thumb of two
phalanges; the paper's model had 1,947 elements and 1,596 nodes) and a larger one (four fingers
of three phalanges, h = ``--large-h``), timed on one motion. Motions (jaxfem.hand.standard_motions):
thumb flexion (45 + 60 degrees), wrist side-to-side (30), wrist up-down (45), 10 frames each.
Scars (the paper's relative elasticity 5.1, Sec. 3.2): a small one inside the wrist's palm side,
a large one from the wrist onto the forearm. A motion is restricted where Newton fails at every
cut-back or where the maximum strain over the area of interest passes the stated limit: LIMIT x
the normal hand's maximum there at the motion's full range (the scarred hand may not strain its
skin much beyond what the normal motion asks of it).

Area of interest (the paper "ignored strains other than in the area of interest"): AREA, the
palm-side skin of the wrist and the forearm in the strip |x| <= 16 mm, where both scars lie. The full-skin
maximum is kept beside it (``max_strain``): it sits at the box model's re-entrant edges (the palm
overhanging the wrist), where strain is mesh-dependent, and barely feels a scar. The maxima over
OTHER_AREAS are reported too, from the same solves.

The strain threshold (the change of growth rate the paper finds at 80-90 % of a motion) is found
per run by refine.threshold.ThresholdRule.find (the one definition: the rising hinge, a threshold
only where the rate rises >= 1.25x with p < 0.01) through ``jaxfem.hand.run_motion(detector=...)``,
on the area's maximum strain against the marked point's displacement: a threshold with its
``fraction`` of the motion and 95 % profile-likelihood interval, or none with why (the hinge kept).

Tracking (issue 25 item 5, ``_hand_tracking.py``): a synthetic range sequence of the moving hand
(a finer mesh, random angles and pose, depth noise, part of the hand unseen) tracked by
refine.hand from the unlabelled clouds and from the marked points; joint-angle errors, seconds per
frame, skin-strain RMS against the truth; seeds 0-2, from the clouds, the markers and both. The
threshold's truth (``_hand_threshold.py``): the rising hinge of the fine noise-free curve against
the detection on the coarse model's curve at tracked joint angles (and with raw strain noise), a
threshold only where the growth rate rises >= 1.25x (refine.threshold.ThresholdRule, both sides);
the hinge on three mesh sizes and over longer motions (``_threshold_mesh.py``). The scar found
in skin data (the committed benchmarks/results/scar.json: its shape and relative elasticity)
placed on the wrist of a hand meshed fine enough to hold it, with a strain limit from the
literature (STRAIN_LIMIT).

    python benchmarks/hand.py --only tracking threshold found-scar   # these sections into the last hand.json
    python benchmarks/hand.py --only threshold-refined               # the longer up-down motion's estimate on
                                                                     # the model refined at the wrist (_threshold_mesh)
    python benchmarks/hand.py --only threshold --reuse-curves        # the threshold analysed again from
                                                                     # results/hand_threshold.npz or hand.json

Writes benchmarks/results/hand.json (with ``targets``) and hand.png (the curves).
"""

from __future__ import annotations

import argparse
import json
import re
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]
sys.path.insert(0, str(ROOT))
sys.path.append(str(Path(__file__).resolve().parent))  # last: a script here named like a package must not shadow it
OUT = Path(__file__).parent / "results"

import jaxfem as jf  # noqa: E402
from jaxfem.hand import (PAPER, Box, HandDimensions, HandModel, Scar, default_body, hand_mesh,  # noqa: E402
                         plot_curves, reachable, run_motion, scar_cells, skin_area, skin_strain_function,
                         standard_motions, write_motion_series)

import _hand_threshold  # noqa: E402
import _hand_tracking  # noqa: E402
import _threshold_mesh  # noqa: E402

RATIO = 5.1  # the paper's relative elasticity of the "more abnormal" scar areas
LIMIT = 1.25  # the strain limit, x the normal hand's full-range maximum of the same motion
OTHER_LIMITS = (1.05, 1.10)  # the reachable share at tighter limits too, from the same curves
#: the area of interest (mm): the palm-side skin (z < -10) of the wrist and the forearm's 40 mm, |x| <= 16 (the
#: scars' strip, at least 8 mm from the side faces, whose edges with the palm's overhang concentrate strain)
AREA = Box((-16.0, -56.1, -20.0), (16.0, 0.1, -10.0))
OTHER_AREAS = {"wrist (all sides)": Box((-24.1, -16.1, -20.0), (24.1, 0.1, 20.0)),
               "palm-side wrist and forearm, full width": Box((-24.1, -56.1, -20.0), (24.1, 0.1, -10.0)),
               "palm-side strip, |x| <= 12": Box((-12.0, -56.1, -20.0), (12.0, 0.1, -10.0))}
#: the skin strain limit (Green-Lagrange, over the area of interest): excised human skin fails at 54 +- 17 %
#: engineering strain (Ni Annaidh et al. 2012, J. Mech. Behav. Biomed. Mater. 5:139-148, 56 samples, uniaxial);
#: the mean less two standard deviations, 20 %, i.e. E = ((1.2)^2 - 1) / 2 = 0.22, which a scar (stiffer and less
#: extensible than normal skin: Clark, Cheng & Leung 1996, Burns 22:443-446) should not be asked to pass
STRAIN_LIMIT = 0.22
#: the scar found by the skin diagnosis (benchmarks/scar.py's committed report rows), placed on the wrist's palm side
#: (its x along the hand's x) in the layer of elements under the skin (its cells' centres within FOUND_DEPTH mm): the
#: skin's 1-2 mm is thinner than one element, so it is run twice: with the ratio as found, and with the ratio that
#: keeps the skin's in-plane stiffness E t over the layer's thickness T, 1 + (ratio - 1) t / T
FOUND_SEED, FOUND_AT, FOUND_DEPTH, FOUND_H = 0, (0.0, -8.0), 7.0, 12.0
#: the threshold section's area per motion (``_hand_threshold``): the wrist's AREA for the wrist motions,
#: the thumb's own skin (both phalanges, every side) for thumb flexion, whose strain barely reaches the wrist
THRESHOLD_AREAS = {"thumb flexion": Box((39.0, 8.0, -12.0), (96.0, 32.0, 12.0)), "wrist side-to-side": AREA,
                   "wrist up-down": AREA}
SCARS = {"small": Scar(jf.Ellipse(0.0, -8.0, 14.0, 6.0), depth=7.0, ratio=RATIO),
         "large": Scar(jf.Ellipse(0.0, -22.0, 20.0, 20.0), depth=9.0, ratio=RATIO)}


def load() -> float:
    return float(open("/proc/loadavg").read().split()[0])


def build(dims: HandDimensions, h: float, snap: float):
    t = time.perf_counter()
    hand = hand_mesh(default_body(dims), h, snap)
    model = HandModel(hand)
    return hand, model, {"elements": hand.mesh.n_cells, "nodes": hand.mesh.n_nodes, "dofs": model.problem.n_dofs,
                         "free_dofs": int(model.problem.free_mask.sum()), "h_mm": h,
                         "skin_facets": len(hand.skin_facets), "build_s": time.perf_counter() - t}


detect = _hand_threshold.detect_json  # a threshold with its interval or none (ThresholdRule.find), as JSON


def row(r, hand) -> dict:
    centres = hand.mesh.nodes[hand.skin_facets[:, :3]].mean(1)
    at = centres[np.argmax(r.skin_strain[-1])]
    area = r.area if r.area is not None else np.ones(len(centres), bool)
    area_at = centres[area][np.argmax(r.skin_strain[-1][area])]
    others = {} if r.area is None else {k: float(r.skin_strain[-1][skin_area(hand, b)].max())
                                        for k, b in OTHER_AREAS.items()}
    return {"max_strain": float(r.max_strain[-1]), "max_at_mm": at.round(1).tolist(),
            "area_max_strain": float(r.area_max_strain[-1]), "area_max_at_mm": area_at.round(1).tolist(),
            "other_areas_max_strain": others, "reached": r.reached,
            "restricted": r.restricted,
            "limited_by": r.limited_by, "strain_limit": r.strain_limit,
            "s_per_frame": float(np.median(r.seconds)) if len(r.seconds) else None,  # median: frame 1 may compile
            "iterations_per_frame": float(np.mean(r.iterations)) if len(r.iterations) else None,
            "curve": {"fraction": r.fraction.tolist(), "displacement_mm": r.displacement.tolist(),
                      "max_strain": r.max_strain.tolist(), "area_max_strain": r.area_max_strain.tolist()},
            "threshold": r.threshold}


def changes(r, normal, hand) -> dict:
    """The scarred run's maxima against the normal hand's, %, at the last frame both reached."""
    k = min(len(r.fraction), len(normal.fraction)) - 1
    pct = lambda a, b: float(100 * (a[k] / b[k] - 1))  # noqa: E731
    return {"change_pct": pct(r.max_strain, normal.max_strain),
            "area_change_pct": pct(r.area_max_strain, normal.area_max_strain),
            "other_areas_change_pct": {n: pct(r.skin_strain[:, m].max(1), normal.skin_strain[:, m].max(1))
                                       for n, m in ((n, skin_area(hand, b)) for n, b in OTHER_AREAS.items())},
            "compared_at_fraction": float(r.fraction[k])}


def analyse(model, frames, series):
    motions = standard_motions(model.hand.body, frames)
    strains = skin_strain_function(model)
    strains(np.zeros(model.problem.n_dofs), model.params({}))  # compile the strain map outside the timings
    out, results, labels = {}, [], []
    area = skin_area(model.hand, AREA)
    out["area_facets"] = int(area.sum())
    kw = {"strains": strains, "area": area, "detector": detect}
    for name, motion in motions.items():
        normal = run_motion(model, motion, **kw)
        if "compile_s" not in out:  # the first frame solved compiles the solver
            out["compile_s"] = float(normal.seconds[0] - np.median(normal.seconds[1:]))
        limit = LIMIT * normal.area_max_strain[-1]
        rows = {"none": row(normal, model.hand)}
        results.append(normal)
        labels.append(name)
        for scar_name, scar in SCARS.items():
            r = run_motion(model, motion, scar=scar, strain_limit=limit, **kw)
            rows[scar_name] = row(r, model.hand) | changes(r, normal, model.hand) | {
                "scar_cells": int(scar_cells(model.hand, scar).sum()),
                "reached_at_limit": {f"{f:g}x": reachable(r.fraction, r.area_max_strain, f * normal.area_max_strain[-1])
                                     for f in OTHER_LIMITS + (LIMIT,)},
                "reached_at_literature_limit": reachable(r.fraction, r.area_max_strain, STRAIN_LIMIT)}
            results.append(r)
            labels.append(f"{name}, {scar_name} scar")
            if series:
                write_motion_series(r, model.hand, Path(series) / scar_name, E=model.moduli(scar)[0])
        if series:
            write_motion_series(normal, model.hand, Path(series) / "none")
        out[name] = rows
        print(name, {k: (round(v["max_strain"], 4), round(v["area_max_strain"], 4), round(v["reached"], 3),
                         v["threshold"].get("fraction")) for k, v in rows.items()}, flush=True)
    return out, results, labels


def fine(h, frames=3) -> dict:
    """The wrist motions of the paper-size hand on a finer mesh (``h`` mm): how the maximum strain
    (over all the skin and over the area of interest) and the scars' effects move with the mesh
    (re-entrant box edges concentrate strain)."""
    hand, model, size = build(PAPER, h, 2.5)
    area = skin_area(hand, AREA)
    out = {"size": size, "frames": frames, "area_facets": int(area.sum())}
    for name, motion in standard_motions(hand.body, frames).items():
        if name.startswith("wrist"):
            normal = run_motion(model, motion, area=area)
            out[name] = {"none": float(normal.max_strain[-1]), "area_none": float(normal.area_max_strain[-1])}
            for k, s in SCARS.items():
                out[name] |= {f"{k}_{key}": v for key, v in
                              changes(run_motion(model, motion, scar=s, area=area), normal, hand).items()}
            print("finer", name, out[name], flush=True)
    return out


def found_scar(seed: int = FOUND_SEED):
    """The scar the skin diagnosis found in benchmarks/results/scar.json's row ``seed`` (its shape's
    half sides and angle, its relative elasticity) as a :class:`jaxfem.hand.Scar` at FOUND_AT."""
    row = next(r for r in json.loads((OUT / "scar.json").read_text())["rows"] if r["seed"] == seed)
    m = re.search(r"(rectangle|ellipse) at \(([-\d.]+), ([-\d.]+)\) (?:half sides|semi-axes) \(([-\d.]+), "
                  r"([-\d.]+)\) angle ([-\d.]+) deg", row["chosen"])
    if m is None:
        raise SystemExit(f"scar.json row {seed}: no rectangle or ellipse in {row['chosen']!r}")
    a, b, angle = float(m[4]), float(m[5]), np.radians(float(m[6]))
    cx, cy = FOUND_AT
    outline = (jf.Rect(cx - a, cy - b, cx + a, cy + b, angle) if m[1] == "rectangle"
               else jf.Ellipse(cx, cy, a, b, angle))
    meta = {"from": f"benchmarks/results/scar.json row seed={seed}", "chosen": row["chosen"], "shape": m[1],
            "half_sides_mm": [a, b], "angle_deg": float(m[6]), "ratio": row["ratio"], "ratio_std": row["ratio_std"],
            "truth_ratio": row["truth"]["ratio"], "placed_at_mm": list(FOUND_AT), "depth_mm": FOUND_DEPTH}
    return Scar(outline, FOUND_DEPTH, row["ratio"]), meta | {"skin_thickness_mm": row["truth"]["thickness"]}


def found_scar_section(model, size, frames) -> dict:
    """The found scar on the wrist: each motion's maximum strain with and without it, restriction at
    STRAIN_LIMIT (the reachable fraction)."""
    scar, meta = found_scar()
    cells = scar_cells(model.hand, scar)
    z = model.hand.mesh.nodes[np.unique(model.hand.mesh.cells[cells]), 2]
    layer = float(z.max() - z.min())
    equivalent = Scar(scar.outline, scar.depth, 1 + (scar.ratio - 1) * meta["skin_thickness_mm"] / layer)
    area = skin_area(model.hand, AREA)
    strains = skin_strain_function(model)
    out = {"scar": meta | {"cells": int(cells.sum()), "layer_mm": layer, "equivalent_ratio": equivalent.ratio},
           "model": size, "strain_limit": STRAIN_LIMIT, "frames": frames}
    for name, motion in standard_motions(model.hand.body, frames).items():
        kw = {"area": area, "strain_limit": STRAIN_LIMIT, "strains": strains}
        normal = run_motion(model, motion, **kw)
        out[name] = {"none": {"area_max_strain": float(normal.area_max_strain[-1]), "reached": normal.reached}}
        for key, sc in (("found", scar), ("equivalent", equivalent)):
            r = run_motion(model, motion, scar=sc, **kw)
            out[name][key] = {"area_max_strain": float(r.area_max_strain[-1]), "reached": r.reached,
                              "limited_by": r.limited_by} | changes(r, normal, model.hand)
        print("found scar", name, out[name], flush=True)
    return out


def targets(res) -> dict:
    paper, motions = res["sizes"]["paper"], [m for m in res["paper"] if m not in ("compile_s", "area_facets")]
    t = {"paper_size": {"target": "1,500-3,000 tet10 elements (the paper: 1,947 elements, 1,596 nodes)",
                        "elements": paper["elements"], "pass": 1500 <= paper["elements"] <= 3000}}
    if "large" in res["sizes"]:
        t["larger_model"] = {"target": ">= 3x the paper-size hand's elements, solved",
                             "elements": res["sizes"]["large"]["elements"],
                             "pass": res["sizes"]["large"]["elements"] >= 3 * paper["elements"]
                             and res["large_motion"]["reached"] == 1.0}
    rise = {m: {s: res["paper"][m][s]["area_change_pct"] for s in SCARS} for m in motions if m.startswith("wrist")}
    t["scar_raises_max_strain"] = {  # the issue: the scar "raises the maximum strain of some motions"
        "target": "each wrist scar raises the maximum strain over the area of interest of some (at least one) wrist "
                  "motion (the paper: +6 % side-to-side with a small scar, +64.44 % up-down, +148.43 % a large one)",
        "area_change_pct": rise, "each_motion_each_scar": all(v > 0 for r in rise.values() for v in r.values()),
        "pass": all(any(r[s] > 0 for r in rise.values()) for s in SCARS)}
    t |= _hand_threshold.found_target(res)
    big = {m: res["paper"][m]["large"]["reached"] for m in motions}
    t["large_scar_restricts"] = {  # no pass: the target with a stated limit is ..._at_literature_limit
        "informational": f"the large scar's reachable share at {LIMIT}x the normal hand's full-range maximum over the "
                         "area (and at tighter relative limits); a relative limit is not the issue's, whose target "
                         "with a stated limit is large_scar_restricts_at_literature_limit",
        "reached": big, "reached_at_limit": {m: res["paper"][m]["large"].get("reached_at_limit") for m in motions}}
    spf = res["paper"][motions[0]]["none"]["s_per_frame"]
    t["seconds_per_frame"] = {"target": "< 10 s per frame at paper size on 2 shared cores", "s": spf,
                              "load": res["load"], "pass": spf is not None and spf < 10}
    lit = {m: reachable(np.asarray(c["fraction"]), np.asarray(c["area_max_strain"]), STRAIN_LIMIT)
           for m in motions for c in [res["paper"][m]["large"]["curve"]]}
    t["large_scar_restricts_at_literature_limit"] = {
        "target": f"the large scar restricts at least one motion at the stated limit {STRAIN_LIMIT} (Green-Lagrange, "
                  "Ni Annaidh et al. 2012's failure strain less 2 SD)", "reached": lit,
        "pass": any(v < 1 for v in lit.values())}
    t |= _hand_tracking.section_targets(res)
    if "threshold_truth" in res:
        t |= _hand_threshold.targets(res["threshold_truth"])
        if "mesh" in res["threshold_truth"]:
            t |= _threshold_mesh.targets(res["threshold_truth"]["mesh"])
    if "found_scar" in res:
        fs = res["found_scar"]
        ms = [m for m in fs if isinstance(fs[m], dict) and "found" in fs[m]]
        t["found_scar_in_the_hand"] = {
            "target": "the scar found in skin data (scar.json) on the wrist raises the area's maximum strain of a wrist "
                      f"motion; reachable fraction at the limit {STRAIN_LIMIT} reported",
            "area_change_pct": {m: {k: fs[m][k]["area_change_pct"] for k in ("found", "equivalent")} for m in ms},
            "reached": {m: {k: fs[m][k]["reached"] for k in ("found", "equivalent")} for m in ms},
            "pass": any(fs[m]["found"]["area_change_pct"] > 0 for m in ms if m.startswith("wrist"))}
    return t


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--large-h", type=float, default=16.0)
    ap.add_argument("--fine-h", type=float, default=12.0, help="the paper-size hand again, finer, for the wrist motions")
    ap.add_argument("--paper-only", action="store_true", help="skip the larger and finer hands (carried from the "
                    "last hand.json, marked 'carried')")
    ap.add_argument("--fine-only", action="store_true", help="rerun only the finer mesh's wrist motions and update "
                    "mesh_dependence in the last hand.json")
    ap.add_argument("--series", default=None, help="folder for the ParaView series (not written by default)")
    ap.add_argument("--only", nargs="+", choices=("tracking", "threshold", "threshold-refined", "found-scar"),
                    default=None, help="run only these sections, into the last hand.json (threshold-refined: the "
                    "longer motion's estimate on the wrist-refined model alone)")
    ap.add_argument("--reuse-curves", action="store_true", help="--only threshold: analyse the solves saved in "
                    "results/hand_threshold.npz (or, without it, the curves in the last hand.json) again instead of "
                    "solving")
    ap.add_argument("--seeds", nargs="+", type=int, default=None, help="--only tracking: track these seeds only, the "
                    "other seeds' runs kept from the last hand.json (marked 'carried')")
    ap.add_argument("--thumb-h", type=float, default=None, help="--only tracking: the tracking model refined along "
                    "the thumb to this element length (mm; _hand_tracking.thumb_model)")
    ap.add_argument("--profile", choices=tuple(_hand_tracking.PROFILES), default="steady", help="--only tracking: the "
                    "motion (stop-reverse: into 'tracking[_thumb]_stop-reverse')")
    ap.add_argument("--kinds", nargs="+", choices=_hand_tracking.KINDS, default=_hand_tracking.KINDS)
    args = ap.parse_args(argv)
    frames = 3 if args.quick else 10
    if args.only:
        return sections(args.only, frames, args.reuse_curves, args.seeds, args.thumb_h, args.profile, args.kinds)
    if args.fine_only:
        res = json.loads((OUT / "hand.json").read_text())
        res["mesh_dependence"] = fine(args.fine_h) | {"load": load()}
        (OUT / "hand.json").write_text(json.dumps(res, indent=1, default=float))
        return
    res = {"load_start": load(), "frames": frames, "ratio": RATIO, "strain_limit_factor": LIMIT,
           "scars": {k: {"outline": v.outline.params.tolist(), "depth_mm": v.depth, "ratio": v.ratio}
                     for k, v in SCARS.items()},
           "area_of_interest": {"box_mm": [AREA.lo, AREA.hi], "others": {k: [b.lo, b.hi] for k, b in OTHER_AREAS.items()}},
           "threshold": "refine.threshold.ThresholdRule.find on the area's max strain vs the marked point's "
                        "displacement (jaxfem.hand.run_motion(detector=...)): a threshold (fraction of the motion, "
                        "95 % interval) or none with why",
           "sizes": {}}
    hand, model, res["sizes"]["paper"] = build(PAPER, 24.0, 4.5)
    print("paper-size hand", res["sizes"]["paper"], flush=True)
    res["paper"], results, labels = analyse(model, frames, args.series)
    if args.paper_only and (OUT / "hand.json").exists():
        old = json.loads((OUT / "hand.json").read_text())
        for key in ("large_motion", "mesh_dependence"):
            if key in old:
                res[key] = old[key] | {"carried": "from the previous hand.json (not rerun; --paper-only)"}
        if "large" in old["sizes"]:
            res["sizes"]["large"] = old["sizes"]["large"] | {"carried": "from the previous hand.json"}
    elif not args.quick:
        big, bmodel, res["sizes"]["large"] = build(HandDimensions(), args.large_h, 2.5)
        print("larger hand", res["sizes"]["large"], flush=True)
        motion = standard_motions(big.body, 5)["wrist up-down"]
        t0 = time.perf_counter()
        r = run_motion(bmodel, motion)
        res["large_motion"] = row(r, big) | {"first_call_s": time.perf_counter() - t0, "frames": 5}
        res["mesh_dependence"] = fine(args.fine_h)
    for key in ("tracking", "threshold_truth", "found_scar"):  # sections run with --only, kept
        if (OUT / "hand.json").exists() and key in (old := json.loads((OUT / "hand.json").read_text())):
            res[key] = old[key]
    res["load"] = load()
    res["targets"] = targets(res)
    OUT.mkdir(exist_ok=True)
    (OUT / "hand.json").write_text(json.dumps(res, indent=1, default=float))
    plot_curves(results, OUT / "hand.png", labels)
    print(json.dumps(res["targets"], indent=1, default=float))


def sections(only, frames, reuse=False, seeds=None, thumb_h=None, profile="steady", kinds=_hand_tracking.KINDS):
    """The --only sections, merged into the last hand.json (its targets recomputed); ``seeds``: the
    tracking seeds run (default all; the others' runs carried); ``thumb_h``: the tracking model's
    thumb refined to this length (mm; default the paper-size model)."""
    res = json.loads((OUT / "hand.json").read_text())
    hand, model, size = build(PAPER, 24.0, 4.5)
    fine = None
    if "tracking" in only:  # with --thumb-h into "tracking_thumb" (beside the paper-size model's, not in the targets)
        key, tmodel = ("tracking", model) if thumb_h is None else ("tracking_thumb", _hand_tracking.thumb_model(thumb_h))
        key += "" if profile == "steady" else f"_{profile}"
        strains = skin_strain_function(tmodel)
        old = res.get(key, {}).get("runs", [])
        res[key] = {"load_start": load()} | _hand_tracking.seeds(tmodel, strains, AREA, seeds=seeds or _hand_tracking.SEEDS,
                                                                 profile=_hand_tracking.PROFILES[profile], kinds=kinds)
        res[key]["load"] = load()
        res[key]["thumb_h_mm"] = thumb_h  # None: the paper-size model as it is
        res[key]["runs"] = _hand_tracking.merge_runs(old, res[key]["runs"])
        res[key]["seeds"] = [r["seed"] for r in res[key]["runs"]]
    if "found-scar" in only:
        _, fine, fine_size = build(PAPER, FOUND_H, 4.5)
    if "threshold" in only:
        make_fine = lambda: fine if fine is not None else build(PAPER, FOUND_H, 4.5)[1]  # noqa: E731
        cache = OUT / "hand_threshold_mesh"  # the mesh study's solves (not committed)
        res["threshold_truth"] = _hand_threshold.section(res.get("threshold_truth", {}), model, make_fine, reuse,
                                                         THRESHOLD_AREAS, AREA, OUT / "hand_threshold.npz",
                                                         lambda: _threshold_mesh.finest_curves(THRESHOLD_AREAS, cache))
        res["threshold_truth"]["mesh"] = _threshold_mesh.convergence(THRESHOLD_AREAS, cache)
        res["threshold_truth"]["longer"] = _threshold_mesh.longer_motions(model, THRESHOLD_AREAS, cache)
    if "threshold" in only or "threshold-refined" in only:  # the longer motion's estimate refined at the wrist
        res["paper"] = _hand_threshold.redetect(res["paper"])
        res["threshold_truth"]["longer_wrist_refined"] = _threshold_mesh.longer_refined(
            res["threshold_truth"]["longer"], THRESHOLD_AREAS, OUT / "hand_threshold_mesh") | {"load": load()}
    if "found-scar" in only:
        res["found_scar"] = found_scar_section(fine, fine_size, frames) | {"load": load()}
    res["targets"] = targets(res)
    (OUT / "hand.json").write_text(json.dumps(res, indent=1, default=float))
    print(json.dumps({k: v.get("pass") for k, v in res["targets"].items()}, indent=1, default=bool))


if __name__ == "__main__":
    main()
