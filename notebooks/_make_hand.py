"""Write notebooks/hand.ipynb from the cells below (executed with ``--execute``).

    python notebooks/_make_hand.py --execute
"""

from pathlib import Path

import sys

from _nbgen import write

CELLS = [
    ("md", """# The hand and the burn scar (the paper's Sec. 5)

A box-like hand/wrist/forearm (`examples.hand`): soft tissue (neo-Hookean, nu 0.49, locking-free
`tet10`) around rigid bones that its joints turn (the wrist about two axes, each thumb phalanx about
one). The scar found in skin data (the committed skin diagnosis of `benchmarks/scar.py`,
`benchmarks/results/scar.json`: its shape and relative elasticity) placed on the palm side of the
wrist, and the skin's strain during two wrist motions with and without it. Then the moving hand
tracked from a synthetic range sequence, without correspondences and from a few marked points. The hand here is a coarse one (no
fingers, ~900 elements) so that the notebook runs in a few minutes (marked slow in tests/test_notebooks.py); `benchmarks/hand.py` runs the
paper-size hand (2,412 elements) and a larger one.

The maximum strain is taken over an **area of interest** (the paper "ignored strains other than in
the area of interest"), the benchmark's: the palm-side skin of the wrist and forearm within
|x| <= 16 mm (the wrist is 48 mm wide), where the scar lies, away from the side faces. The
full-skin maximum sits at the box model's re-entrant edges (the palm overhangs the wrist), where
strain depends on the mesh, and barely feels a scar; it is kept beside the area's."""),
    ("code", r"""from dataclasses import replace
import numpy as np
import matplotlib.pyplot as plt
from mpl_toolkits.mplot3d.art3d import Poly3DCollection
from IPython.display import Image, display
import jaxfem as jf
from examples.hand import (PAPER, Box, HandModel, Motion, Scar, default_body, hand_mesh, plot_curves, run_motion,
                         scar_cells, skin_area, skin_strain_function)
from refine.threshold import ThresholdRule

dims = replace(PAPER, forearm=(48.0, 20.0, 28.0), palm=(48.0, 40.0, 26.0), fingers=0, thumb_phalanges=(20.0, 20.0))
hand = hand_mesh(default_body(dims), 30.0, 4.5)
model = HandModel(hand)  # compiles once: every motion and every scar reuses it
# the scar the skin diagnosis found (benchmarks/results/scar.json, seed 0's row): a rectangle and its relative
# elasticity, placed on the palm side of the wrist in the layer of elements under the skin (8 mm: the skin's
# 1-2 mm is thinner than one element here)
import json, re, pathlib
rows = json.loads(pathlib.Path("../benchmarks/results/scar.json").read_text())["rows"]
row = next(r for r in rows if r["seed"] == 0)  # by its seed: the rows are not in seed order
a, b, angle = map(float, re.search(r"half sides \(([-\d.]+), ([-\d.]+)\) angle ([-\d.]+) deg", row["chosen"]).groups())
print("found in skin data:", row["chosen"].split("]")[0] + "]", f"ratio {row['ratio']:.2f} +- {row['ratio_std']:.2f}",
      f"(truth {row['truth']['ratio']:.2f})")
scar = Scar(jf.Rect(-a, -8.0 - b, a, -8.0 + b, np.radians(angle)), depth=8.0, ratio=row["ratio"])
area = skin_area(hand, Box((-16.0, -36.1, -20.0), (16.0, 0.1, -10.0)))  # palm-side strip of wrist and forearm
print(hand.mesh.n_cells, "tet10 elements,", hand.mesh.n_nodes, "nodes;", int(scar_cells(hand, scar).sum()),
      "scar elements;", int(area.sum()), "of", len(area), "skin facets in the area of interest")"""),
    ("md", """## Two wrist motions, with and without the scar

Each motion takes 8 frames to its full range (wrist up 30 degrees, to the side 20 degrees). The
threshold of each strain-displacement curve (where the strain's growth speeds up) is found by
`refine.threshold.ThresholdRule.find` through `run_motion`'s `detector` hook: the one definition
the benchmarks use too, the rising hinge of a two-segment fit, called a threshold only where the
growth rate past it is at least 1.25x the rate before and the change is significant (F test
p < 0.01). A curve that bends evenly has none (the best hinge of any curve is kept beside, as
`hinge`); a threshold comes with its 95 % profile-likelihood interval. Over ranges as short as
these a wrist curve may well have none; `benchmarks/hand.py` gives each motion's answer on the
paper-size hand against a finer mesh's (`threshold_found`), and the wrist bent up over a normal
wrist's 67.5 degrees, which has one. The scarred hand is restricted where its maximum strain over the area
of interest passes a stated limit: 0.22 (Green-Lagrange; excised human skin fails at 54 +- 17 %
engineering strain, Ni Annaidh et al. 2012, J. Mech. Behav. Biomed. Mater. 5:139-148; the mean
less two standard deviations, 20 %), or where Newton fails at every cut-back."""),
    ("code", """strains = skin_strain_function(model)
rule = ThresholdRule()  # min_rise 1.25, alpha 0.01
detect = lambda x, s: rule.find(x, s).to_json()
motions = [Motion("wrist up-down", {"wrist_flexion": 30.0}, "thumb tip", 8),
           Motion("wrist side-to-side", {"wrist_deviation": 20.0}, "thumb tip", 8)]
runs = []
for m in motions:
    normal = run_motion(model, m, area=area, detector=detect, strains=strains)
    scarred = run_motion(model, m, scar=scar, area=area, detector=detect, strains=strains,
                         strain_limit=0.22)
    runs += [normal, scarred]
    for label, r in (("normal", normal), ("scar", scarred)):
        t = r.threshold
        said = (f"threshold at {100 * t['fraction']:.0f} % of the displacement "
                f"[{100 * t['fraction_interval'][0]:.0f}, {100 * t['fraction_interval'][1]:.0f}] %"
                if t["has_threshold"] else f"no threshold ({t['why_none']})")
        print(f"{m.name:20s} {label:6s} max strain: area {r.area_max_strain[-1]:.4f}, all skin {r.max_strain[-1]:.4f}; "
              f"{said}; rate x{t['hinge']['rise']:.2f} at the hinge, p = {t['hinge']['p_value']:.1e}; "
              f"reached {100 * r.reached:.0f} %" + (f" (restricted: {r.limited_by})" if r.restricted else ""))
    print(f"{'':20s} scar changes the area's maximum by {100 * (scarred.area_max_strain[-1] / normal.area_max_strain[-1] - 1):+.1f} %, "
          f"the full skin's by {100 * (scarred.max_strain[-1] / normal.max_strain[-1] - 1):+.1f} %")"""),
    ("md", """## Strain-displacement curves with their thresholds

Solid: the normal hand, dashed: with the scar; diamonds: the threshold with its interval (on a
curve that has one); thin
dotted lines: the strain limit of the scarred motion. A restricted motion says where it stopped
being allowed."""),
    ("code", """import tempfile, pathlib
png = pathlib.Path(tempfile.mkdtemp()) / "hand_curves.png"
display(Image(plot_curves(runs, png, [f"{r.motion.name}" + (", scar" if r.scar else "") for r in runs])))"""),
    ("md", """## The skin's strain in 3D

The deformed skin at the full wrist flexion, coloured by the skin's largest principal strain
(facets drawn by their corner nodes), without and with the scar (its outline in black)."""),
    ("code", """def draw(ax, r, title, vmax):
    x = hand.mesh.nodes + r.u[-1]
    tri = x[hand.skin_facets[:, :3]]
    pc = Poly3DCollection(tri, cmap="viridis", edgecolor="k", linewidths=0.1)
    pc.set_array(r.skin_strain[-1]); pc.set_clim(0, vmax)
    ax.add_collection3d(pc)
    lo, hi = x.min(0), x.max(0)
    ax.set_xlim(lo[0], hi[0]); ax.set_ylim(lo[1], hi[1]); ax.set_zlim(lo[2], hi[2])
    ax.set_box_aspect(hi - lo); ax.view_init(elev=-35, azim=-60); ax.set_title(title, fontsize=9)
    if r.scar is not None:
        t = np.linspace(0, 2 * np.pi, 80)
        e = r.scar.outline  # the found rectangle's corners
        ax.plot([e.x0, e.x1, e.x1, e.x0, e.x0], [e.y0, e.y0, e.y1, e.y1, e.y0], np.full(5, lo[2]), "k-", lw=1)
    return pc

fig = plt.figure(figsize=(10, 4.5))
vmax = max(runs[0].skin_strain[-1].max(), runs[1].skin_strain[-1].max())
for i, (r, title) in enumerate(zip(runs[:2], ("normal hand, wrist up 30 deg", "with the scar"))):
    pc = draw(fig.add_subplot(1, 2, i + 1, projection="3d"), r, title, vmax)
fig.colorbar(pc, ax=fig.axes, shrink=0.6, label="skin strain (max principal Green-Lagrange)")
import io
buf = io.BytesIO(); fig.savefig(buf, format="png", dpi=90); plt.close(fig)
display(Image(buf.getvalue()))  # plot_curves switched matplotlib to Agg: show the PNG"""),
    ("md", """## Tracking the moving hand

A synthetic range sequence (`examples.hand.range`): joint angles and a global pose drawn
at random under a seed, the hand solved on a **finer** mesh (h = 15 mm, not the tracker's), seen
by one orthographic range camera from the back of the hand (depth noise 0.2 mm, a structured-light
scanner's; the palm side never seen, the flexed thumb partly hidden, the forearm's end out of
view), and 13 marked points with 0.1 mm noise. `examples.hand.HandTracker` fits the joint angles
and the pose of the notebook's coarse model to each frame, (a) from the unlabelled cloud (point to
deformed-surface distances) and (b) from the markers, by Levenberg-Marquardt with the exact
Jacobian through the solve (the angles drive the bones' kinematic Dirichlet data)."""),
    ("code", """from examples.hand import HandTracker, TrackConfig, angle_errors, skin_strain_on
from examples.hand.range import hand_range_sequence

seq = hand_range_sequence(seed=0, frames=4, h=15.0, dims=dims)  # steps of <= 15 degrees
tracker = HandTracker(model, TrackConfig(noise=seq.noise, marker_noise=seq.marker_noise))
print("truth (deg):", dict(zip(seq.names, np.degrees(seq.angles[-1]).round(1))), "; points per frame:",
      [len(c) for c in seq.clouds])
fits = {"clouds": tracker.track(clouds=seq.clouds),
        "markers": tracker.track(markers=(seq.marker_reference, seq.markers))}
for kind, f in fits.items():
    err = angle_errors(f, seq.angles)
    truth = [skin_strain_on(seq.hand, e, hand) for e in seq.skin_strain]
    est = [np.asarray(strains(fit.u, model.params(dict(zip(seq.names, fit.angles))))[0]) for fit in f]
    rms = [np.sqrt(np.nanmean((e - t)[area] ** 2)) for e, t in zip(est, truth)]
    print(f"{kind:8s} largest angle error per frame (deg): {np.abs(err).max(axis=1).round(3)}; "
          f"skin-strain RMS over the area: {np.round(rms, 4)}; s per frame: {[round(x.seconds, 1) for x in f]}")"""),
    ("code", """# the last frame: its cloud (scanner frame, brought back by the fitted pose) on the fitted skin
from examples.hand.range import pose_matrix
f = fits["clouds"][-1]
R, t = pose_matrix(f.pose)
pts = (seq.clouds[-1] - t) @ R
x = hand.mesh.nodes + f.u
fig = plt.figure(figsize=(6, 5)); ax = fig.add_subplot(projection="3d")
ax.add_collection3d(Poly3DCollection(x[hand.skin_facets[:, :3]], facecolor="0.85", edgecolor="0.5", linewidths=0.2, alpha=0.5))
ax.scatter(*pts[::3].T, s=1, c="C3")
lo, hi = x.min(0), x.max(0)
ax.set_xlim(lo[0], hi[0]); ax.set_ylim(lo[1], hi[1]); ax.set_zlim(lo[2], hi[2]); ax.set_box_aspect(hi - lo)
ax.view_init(elev=50, azim=-70); ax.set_title("last frame: range points (red) on the tracked skin", fontsize=9)
buf = io.BytesIO(); fig.savefig(buf, format="png", dpi=90); plt.close(fig)
display(Image(buf.getvalue()))"""),
    ("md", """`examples.hand.write_motion_series(result, hand, folder)` writes the same frames as ParaView
series (the volume and the skin surface), and `benchmarks/hand.py` the paper-size comparison in
`benchmarks/results/hand.json`."""),
]


if __name__ == "__main__":
    write(CELLS, Path(__file__).with_name("hand.ipynb"), execute="--execute" in sys.argv)
