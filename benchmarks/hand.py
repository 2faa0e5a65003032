"""The articulated hand of the paper's Sec. 5: model size, seconds per frame, scar strain.

The articulated hand of the paper's Sec. 5 (examples.hand): model size, seconds per frame, and the
maximum skin strain of its three motions with and without a scar on the wrist.

    python -m benchmarks hand                 # paper-size hand, 3 motions x (no, small, large scar); larger hand timed
    python -m benchmarks hand --quick         # 3 frames per motion, no larger hand
    python -m benchmarks hand --paper-only    # the paper-size hand's motions only; the larger hand's and the
                                              # finer mesh's entries are carried from the last hand.json (marked)
    python -m benchmarks hand --fine-only     # only the finer mesh's wrist motions, into the last hand.json
    python -m benchmarks hand --series out/hand   # also the ParaView series of every run

Sizes: the paper-size hand (examples.hand.PAPER at h = 24 mm: one finger block, thumb of two
phalanges; the paper's model had 1,947 elements and 1,596 nodes) and a larger one (four fingers
of three phalanges, h = ``--large-h``), timed on one motion. Motions (examples.hand.standard_motions):
thumb flexion (45 + 60 degrees), wrist side-to-side (30), wrist up-down (45), 10 frames each.
Scars (the paper's relative elasticity 5.1, Sec. 3.2): a small one inside the wrist's palm side,
a large one from the wrist onto the forearm. A motion is restricted where Newton fails at every
cut-back or where the maximum strain over the area of interest passes the stated limit: LIMIT x
the normal hand's maximum there at the motion's full range (the scarred hand may not strain its
skin much beyond what the normal motion asks of it).
These runs are ``_hand_scars.py``'s (the constants, :func:`analyse`, the finer mesh's :func:`fine`);
this script holds the targets and the command line.

Area of interest (the paper "ignored strains other than in the area of interest"): AREA, the
palm-side skin of the wrist and the forearm in the strip |x| <= 16 mm, where both scars lie. The full-skin
maximum is kept beside it (``max_strain``): it sits at the box model's re-entrant edges (the palm
overhanging the wrist), where strain is mesh-dependent, and barely feels a scar. The maxima over
OTHER_AREAS are reported too, from the same solves.

The strain threshold (the change of growth rate the paper finds at 80-90 % of a motion) is found
per run by refine.threshold.ThresholdRule.find (the one definition: the rising hinge, a threshold
only where the rate rises >= 1.25x with p < 0.01) through ``examples.hand.run_motion(detector=...)``,
on the area's maximum strain against the marked point's displacement: a threshold with its
``fraction`` of the motion and 95 % profile-likelihood interval, or none with why (the hinge kept).

Tracking (issue 25 item 5, ``_hand_tracking.py``): a synthetic range sequence of the moving hand
(a finer mesh, random angles and pose, depth noise, part of the hand unseen) tracked by
examples.hand from the unlabelled clouds and from the marked points; joint-angle errors, seconds per
frame, skin-strain RMS against the truth; seeds 0-2, from the clouds, the markers and both (the
markers alone, noise-limited at 1 degree, judged by their reported uncertainty; their limit
measured by ``_hand_marker_noise.py``). The
threshold's truth (``_hand_threshold.py``): the rising hinge of the fine noise-free curve against
the detection on the coarse model's curve at tracked joint angles (and with raw strain noise), a
threshold only where the growth rate rises >= 1.25x (refine.threshold.ThresholdRule, both sides);
the hinge on three mesh sizes and over longer motions (``_threshold_mesh.py``). The scar found
in skin data (the committed benchmarks/results/scar.json: its shape and relative elasticity)
placed on the wrist of a hand meshed fine enough to hold it, with a strain limit from the
literature (STRAIN_LIMIT; ``_hand_found_scar.py``).

    python -m benchmarks hand --only tracking threshold found-scar   # these sections into the last hand.json
    python -m benchmarks hand --only threshold-refined               # the longer up-down motion's estimate on
                                                                     # the model refined at the wrist (_threshold_mesh)
    python -m benchmarks hand --only marker-noise --thumb-h 6 --seeds 2   # the markers-alone noise limit
                                                                     # (_hand_marker_noise: linearised draws)
    python -m benchmarks hand --only threshold --reuse-curves        # the threshold analysed again from
                                                                     # results/hand_threshold.npz or hand.json

Writes benchmarks/results/hand.json (with ``targets``) and hand.png (the curves).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

OUT = Path(__file__).parent / "results"

from examples.hand import (PAPER, HandDimensions, plot_curves, reachable, run_motion,  # noqa: E402
                         skin_strain_function, standard_motions)

from benchmarks import _hand_marker_noise  # noqa: E402
from benchmarks import _hand_threshold  # noqa: E402
from benchmarks import _hand_tracking  # noqa: E402
from benchmarks import _threshold_mesh  # noqa: E402
from benchmarks._hand_found_scar import FOUND_H, found_scar_section, found_target  # noqa: E402
from benchmarks._hand_scars import (AREA, LIMIT, OTHER_AREAS, RATIO, SCARS, STRAIN_LIMIT, THRESHOLD_AREAS,  # noqa: E402
                         analyse, build, fine, load, row)


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
    t |= _hand_marker_noise.targets(res)
    if "threshold_truth" in res:
        t |= _hand_threshold.targets(res["threshold_truth"])
        if "mesh" in res["threshold_truth"]:
            t |= _threshold_mesh.targets(res["threshold_truth"]["mesh"])
    t |= found_target(res)
    return t


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--large-h", type=float, default=16.0)
    ap.add_argument("--fine-h", type=float, default=12.0, help="the paper-size hand again, finer, for the wrist motions")
    ap.add_argument("--paper-only", action="store_true", help="skip the larger and finer hands (carried from the "
                    "last hand.json, marked 'carried')")
    ap.add_argument("--fine-only", action="store_true", help="rerun only the finer mesh's wrist motions and update "
                    "mesh_dependence in the last hand.json")
    ap.add_argument("--series", default=None, help="folder for the ParaView series (not written by default)")
    ap.add_argument("--only", nargs="+", choices=("tracking", "marker-noise", "threshold", "threshold-refined",
                                                  "found-scar"),
                    default=None, help="run only these sections, into the last hand.json (threshold-refined: the "
                    "longer motion's estimate on the wrist-refined model alone; marker-noise: the markers-alone noise "
                    "limit, _hand_marker_noise, of --seeds, default 2)")
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
        return 0
    res = {"load_start": load(), "frames": frames, "ratio": RATIO, "strain_limit_factor": LIMIT,
           "scars": {k: {"outline": v.outline.params.tolist(), "depth_mm": v.depth, "ratio": v.ratio}
                     for k, v in SCARS.items()},
           "area_of_interest": {"box_mm": [AREA.lo, AREA.hi], "others": {k: [b.lo, b.hi] for k, b in OTHER_AREAS.items()}},
           "threshold": "refine.threshold.ThresholdRule.find on the area's max strain vs the marked point's "
                        "displacement (examples.hand.run_motion(detector=...)): a threshold (fraction of the motion, "
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
    return 0


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
    if "marker-noise" in only:  # the markers-alone noise limit (linearised): "marker_noise[_thumb]"
        key, mmodel = ("marker_noise", model) if thumb_h is None else ("marker_noise_thumb",
                                                                       _hand_tracking.thumb_model(thumb_h))
        res[key] = {"load_start": load(), "runs": [_hand_marker_noise.noise_limit(mmodel, s) for s in seeds or (2,)],
                    "load": load(), "thumb_h_mm": thumb_h}
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
    raise SystemExit(main())
