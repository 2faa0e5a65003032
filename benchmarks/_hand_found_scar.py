"""benchmarks/hand.py's found-scar section (issue 25 item 4): the scar the skin diagnosis found
(the committed benchmarks/results/scar.json: its shape and relative elasticity) placed on the
wrist of a hand meshed fine enough to hold it, each motion's maximum strain over the area of
interest with and without it, and the reachable fraction at the literature's strain limit
(``_hand_scars.STRAIN_LIMIT``). Split from hand.py (what it computes unchanged).

Units: mm; strain Green-Lagrange (dimensionless).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np

import jaxfem as jf
from examples.hand import Scar, run_motion, scar_cells, skin_area, skin_strain_function, standard_motions

from benchmarks._hand_scars import AREA, STRAIN_LIMIT, changes

OUT = Path(__file__).parent / "results"

#: the scar found by the skin diagnosis (benchmarks/scar.py's committed report rows), placed on the wrist's palm side
#: (its x along the hand's x) in the layer of elements under the skin (its cells' centres within FOUND_DEPTH mm): the
#: skin's 1-2 mm is thinner than one element, so it is run twice: with the ratio as found, and with the ratio that
#: keeps the skin's in-plane stiffness E t over the layer's thickness T, 1 + (ratio - 1) t / T
FOUND_SEED, FOUND_AT, FOUND_DEPTH, FOUND_H = 0, (0.0, -8.0), 7.0, 12.0


def found_scar(seed: int = FOUND_SEED):
    """The scar the skin diagnosis found in benchmarks/results/scar.json's row ``seed`` (its shape's
    half sides and angle, its relative elasticity) as a :class:`examples.hand.Scar` at FOUND_AT."""
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



def found_target(res: dict) -> dict:
    """hand.json's ``found_scar_in_the_hand`` target of the section ``res["found_scar"]`` (none
    without it)."""
    if "found_scar" not in res:
        return {}
    fs = res["found_scar"]
    ms = [m for m in fs if isinstance(fs[m], dict) and "found" in fs[m]]
    return {"found_scar_in_the_hand": {
        "target": "the scar found in skin data (scar.json) on the wrist raises the area's maximum strain of a wrist "
                  f"motion; reachable fraction at the limit {STRAIN_LIMIT} reported",
        "area_change_pct": {m: {k: fs[m][k]["area_change_pct"] for k in ("found", "equivalent")} for m in ms},
        "reached": {m: {k: fs[m][k]["reached"] for k in ("found", "equivalent")} for m in ms},
        "pass": any(fs[m]["found"]["area_change_pct"] > 0 for m in ms if m.startswith("wrist"))}}
