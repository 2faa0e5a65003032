"""benchmarks/hand.py's scar section (issue 25 items 2-4): the paper-size hand's three motions
(examples.hand.standard_motions) with no, a small and a large wrist scar (the paper's relative
elasticity 5.1), the maximum skin strain over the area of interest (AREA) and over the whole
skin, restriction at LIMIT x the normal hand's full-range maximum and at the literature's
STRAIN_LIMIT, the threshold of each curve (``_hand_threshold.detect_json``), and the wrist
motions again on a finer mesh (:func:`fine`). Split from hand.py (what it computes unchanged).

Units: mm; strain Green-Lagrange (dimensionless).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

import jaxfem as jf
from examples.hand import (PAPER, Box, HandDimensions, HandModel, Scar, default_body, hand_mesh, reachable, run_motion,
                         scar_cells, skin_area, skin_strain_function, standard_motions, write_motion_series)

from benchmarks import _hand_threshold

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

