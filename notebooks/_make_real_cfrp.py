"""Write notebooks/real_cfrp.ipynb (run from the repository root: ``python notebooks/_make_real_cfrp.py``;
add ``--execute`` to run it headless and store the outputs; it needs ../shared/data)."""

from __future__ import annotations

import sys
from pathlib import Path

from _nbgen import write

CELLS = [
    ("md", """# A real open-hole coupon: the hole the model forgot, and what is left

The DIC Challenge's Sample 12: twelve speckle images of a carbon-fibre (CFRP) coupon with a hole,
pulled in tension (vertical in the images). We track the speckle, write a measurement bundle whose
initial model **forgot the hole** (the domain is the outline of the tracked points, left whole),
and let the diagnosis find it from the measured motion alone: no tracked point lies in the hole,
and the strain around it is higher than a whole plate's. Then we put the found hole in the model and
ask what is still wrong: the laminate's anisotropy, another material law, or nothing beyond the
noise.

Lengths are in pixels (`scale=1`); the images and DICe's own results are in
`../shared/data/dic-challenge-sample12` (DIC Challenge terms, research use). This takes several
minutes on 2 cores."""),
    ("code", """import sys, tempfile, time
from dataclasses import replace
from pathlib import Path

import cv2
import matplotlib.pyplot as plt
import numpy as np

from refine.bundle.io import Bundle
from refine.cli import track
from refine.diagnosis import diagnose
from refine.diagnosis.candidates import missing_point_regions
from refine.diagnosis.strain_figures import diagnosis_strain_figure, strain_maps_figure

sys.path.insert(0, str(Path("..") / "benchmarks"))
from cfrp import SAMPLE, image_hole  # the hole seen in the image, measured from the pixels

work = Path(tempfile.mkdtemp(prefix="nonrigid-cfrp-"))
start = time.perf_counter()"""),
    ("md", """## 1. Track the speckle

`cut_holes=False` is `nonrigid track --keep-holes`: the tracker still leaves the hole's subsets out
(nothing to correlate on a black disc), but the bundle's domain stays whole, as if the modeller
had forgotten the hole."""),
    ("code", """t = time.perf_counter()
bundle = track(sorted(SAMPLE.glob("oht_cfrp_*.tiff")), work / "cfrp", pattern="speckle", scale=1.0,
               cut_holes=False, quiet=True)
obs = bundle.observations
print(f"{obs.n_points} points x {obs.n_frames} frames tracked in {time.perf_counter() - t:.0f} s; "
      f"domain holes: {len(bundle.experiment.domain.holes)}")
centre, area, width = image_hole(SAMPLE / "oht_cfrp_00.tiff")
print(f"the hole in the image: centre ({centre[0]:.1f}, {centre[1]:.1f}) px, area {area:.0f} px^2 "
      f"(radius {np.sqrt(area / np.pi):.1f} px); specimen width {width:.0f} px")
image = cv2.imread(str(SAMPLE / "oht_cfrp_00.tiff"), cv2.IMREAD_GRAYSCALE)
fig, ax = plt.subplots(figsize=(4, 8))
ax.imshow(image, cmap="gray")
for role, colour in (("boundary", "tab:red"), ("guide", "tab:blue"), ("validate", "tab:orange")):
    m = obs.mask(role)
    ax.plot(*obs.reference[m].T, ".", ms=1.5, color=colour, label=role)
ax.legend(loc="lower right", fontsize=7, markerscale=5)
ax.set_title("tracked points on the reference image");"""),
    ("md", """## 2. What the data show before any model

The strain of the tracked point cloud itself (Green-Lagrange, per triangle of a Delaunay
triangulation of the reference points; triangles that bridge the gap are left out), and the gap in
the points: a place farther than 1.5 point spacings from every tracked point, inside the domain."""),
    ("code", """last = obs.n_frames - 1
fig = strain_maps_figure(obs.reference, {f"measured, frame {last + 1}": obs.displacements[last]})
display(fig)
for c in missing_point_regions(obs.reference, bundle.experiment.domain):
    print(f"gap in the points at ({c.centroid[0]:.1f}, {c.centroid[1]:.1f}), area {c.strength:.0f} px^2 "
          f"(a start for a hole's fit)")"""),
    ("md", """## 3. Diagnose with the hole forgotten

The gap in the points starts a hole; a hole keeps half a DIC subset away from every tracked point
(the bundle's `measurement.subset`: each point's whole subset was correlated on material). An
isotropic model with the hole leaves the ring around it straining more than it says (the laminate
is orthotropic), and a zero-stiffness region over the hole and that ring would fit it better than
the hole alone; the diagnosis therefore also fits the hole in the material law that fitted best
alone (here the fibre-reinforced law), the law's parameters and the hole together, and compares
all of them on held-out points. A hole found with another law is reported with that law."""),
    ("code", """whole = diagnose(bundle)
for f in whole.findings:
    print(f.cause, f.region and (f.region.centroid, f.region.area), f.relative_elasticity, f.law or "")
hole = [f for f in whole.findings if f.cause == "hole"]
if hole:
    r = hole[0].region
    print(f"centre off by {np.hypot(*(np.asarray(r.centroid) - centre)) / width:.2%} of the width "
          f"(target 2 %); area {r.area / area - 1:+.1%} of the image's hole (target 10 %)")
print(f"validation error {whole.errors['baseline']['validation_error']:.4g} -> "
      f"{whole.errors['refined']['validation_error']:.4g} px (gain {whole.errors['gain']:.2f})")
display(diagnosis_strain_figure(whole))"""),
    ("md", """## 4. The hole in the model: what is left?

The found hole becomes a known hole of the domain, and the diagnosis runs again. The laws it can
try are the alternatives of jaxfem's registry (the fibre-reinforced law among them: the
laminate's anisotropy), besides regions of other stiffness; "none" means the holed model explains
the motion within the noise and its propagation."""),
    ("code", """domain = replace(bundle.experiment.domain, holes=(tuple(map(tuple, hole[0].region.polygon)),))
holed = diagnose(Bundle(replace(bundle.experiment, domain=domain), obs, bundle.root))
print("what is left:", holed.chosen.describe())
print(f"initial (holed) model misfit {holed.null.ratio:.2f}x its null level (p = {holed.null.p_value:.2g})")
print(f"validation error: whole model {whole.errors['baseline']['validation_error']:.4g} px, holed model "
      f"{holed.errors['baseline']['validation_error']:.4g} px, after the diagnosis "
      f"{holed.errors['refined']['validation_error']:.4g} px (gain {holed.errors['gain']:.2f})")
display(diagnosis_strain_figure(holed))
print(f"{time.perf_counter() - start:.0f} s in all")"""),
]


if __name__ == "__main__":
    here = Path(__file__).resolve().parent
    write(CELLS, here / "real_cfrp.ipynb", execute="--execute" in sys.argv, cwd=here, timeout=3600)  # a diagnosis cell takes minutes
