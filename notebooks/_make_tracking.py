"""Write notebooks/tracking.ipynb (run from the repository root: ``python notebooks/_make_tracking.py``;
add ``--execute`` to run it headless and store the outputs)."""

from __future__ import annotations

import sys
from pathlib import Path

from _nbgen import write

CELLS = [
    ("md", """# From images to a named cause

A sheet hides a stiffer disc. We photograph it with a painted grid while it is pulled, track the
grid crossings, write a measurement bundle, and let `nonrigid diagnose` say what the uniform model
gets wrong. Everything here is synthetic, so we can compare with the truth at the end; the images are
what a camera would give (blur, noise, 8-bit PNG files), nothing else crosses from the simulation to
the analysis.

A coarse grid (8 mm) and two deformed frames keep this notebook to a few minutes."""),
    ("code", """import json, tempfile, time
from pathlib import Path

import cv2
import matplotlib.pyplot as plt
import numpy as np
from IPython.display import Image, display

import refine
from refine.bundle import ModelSkeleton
from refine.cli import track
from examples.synthetic.render import render_sheet_images
from refine.demo_data import Inclusion, Truth
import jaxfem as jf

work = Path(tempfile.mkdtemp(prefix="nonrigid-tracking-"))
start = time.perf_counter()"""),
    ("md", """## 1. The hidden truth and the images

A 140 x 80 mm sheet is clamped on its left side and pulled 15 % on its right side; the camera looks at
the region [20, 120] x [10, 70] mm at 0.5 mm per pixel, with grid lines every 16 px (8 mm). The
truth is drawn at random under a seed: a disc 4-8 times stiffer than the rest of the sheet."""),
    ("code", """rng = np.random.default_rng(7)
radius = rng.uniform(0.14, 0.18) * 60.0
centre = rng.uniform([20 + 10 + radius, 10 + 10 + radius], [120 - 10 - radius, 70 - 10 - radius])
truth = Truth(inclusions=(Inclusion(jf.Ellipse(*centre, radius, radius), float(rng.uniform(4, 8))),))
hidden = truth.inclusions[0]
print(f"hidden: a disc at ({hidden.shape.cx:.1f}, {hidden.shape.cy:.1f}) mm, radius {radius:.1f} mm, "
      f"{hidden.ratio:.2f}x stiffer")

images, roi_px, scale = render_sheet_images(truth, frames=(0.5, 1.0), pitch_px=16.0, scale_mm_per_px=0.5,
                                            h=3.0, noise_sigma=2.0, seed=7)
paths = []
for k, image in enumerate(images):
    paths.append(work / f"frame_{k}.png")
    cv2.imwrite(str(paths[-1]), np.clip(np.rint(image), 0, 255).astype(np.uint8))
print(f"{len(images)} images of {images.shape[2]} x {images.shape[1]} px; ROI {roi_px} px; "
      f"{time.perf_counter() - start:.0f} s so far")

fig, axes = plt.subplots(1, 2, figsize=(12, 4))
for ax, k in zip(axes, (0, len(images) - 1)):
    ax.imshow(images[k], cmap="gray")
    ax.set_title(f"frame {k}")
    ax.axis("off")"""),
    ("md", """## 2. Track the grid: `nonrigid track`

`refine.cli.track` is the command line

    nonrigid track --pattern grid --scale 0.5 --roi X0,Y0,X1,Y1 frame_0.png frame_1.png frame_2.png --out bundle

called from Python; it writes the bundle directory and returns the bundle read back from it.

The first image is the reference; bundle coordinates are x = column * scale, y = row * scale. The
outer ring of crossings becomes the boundary that drives the model."""),
    ("code", """bundle_dir = work / "bundle"
bundle = track(paths, bundle_dir, pattern="grid", scale=scale, roi=roi_px, model=ModelSkeleton(E=truth.E))"""),
    ("md", """The overlays the command wrote (orange: boundary, green: guide, blue: validate points; a lost
point would be a red x; frame 0 also shows the ROI, dashed, and the bundle's domain):"""),
    ("code", """for k in (0, len(images) - 1):
    display(Image(filename=bundle_dir / "overlays" / f"frame_{k:03d}.png", width=700))"""),
    ("code", """print((bundle_dir / "experiment.toml").read_text())
print("\\n".join((bundle_dir / "points.csv").read_text().splitlines()[:6]), "\\n...")"""),
    ("md", """## 3. Diagnose the bundle

The uniform model is driven by the boundary points; its misfit at the guide points is compared with
what noise explains, then a modulus field localises the problem and hypotheses (a stiffer or softer
region, a hole, another law) compete on held-out points."""),
    ("code", """d = refine.diagnose(bundle, out=work / "diagnosis")  # diagnosed, then written
print(d.summary())"""),
    ("code", """for name in ("regions.png", "residuals.png"):
    display(Image(filename=work / "diagnosis" / name, width=800))"""),
    ("code", """content = d.report()  # report.json; the outlines are shortened here
for finding in content["findings"]:
    if finding["region"]:
        finding["region"]["polygon"] = f"[{len(finding['region']['polygon'])} vertices]"
print(json.dumps({k: v for k, v in content.items() if k != "decision"}, indent=1))"""),
    ("md", """## 4. Found versus hidden"""),
    ("code", """domain = bundle.experiment.domain
diagonal = np.hypot(domain.xmax - domain.xmin, domain.ymax - domain.ymin)
print(f"truth: stiffer-region at ({hidden.shape.cx:.1f}, {hidden.shape.cy:.1f}) mm, "
      f"area {np.pi * radius**2:.0f} mm2, {hidden.ratio:.2f}x")
for f in d.findings:
    if f["region"] is None:
        print("found:", f["cause"], f.get("law"))
        continue
    c = f["region"]["centroid"]
    off = np.hypot(c[0] - hidden.shape.cx, c[1] - hidden.shape.cy)
    print(f"found: {f['cause']} at ({c[0]:.1f}, {c[1]:.1f}) mm, area {f['region']['area']:.0f} mm2, "
          f"{f['relative_elasticity']:.2f}x: centroid off by {off:.2f} mm ({100 * off / diagonal:.1f} % of the "
          f"domain diagonal), ratio off by {100 * (f['relative_elasticity'] / hidden.ratio - 1):+.0f} %")
print(f"whole notebook: {time.perf_counter() - start:.0f} s")"""),
]


if __name__ == "__main__":
    write(CELLS, Path(__file__).with_name("tracking.ipynb"), execute="--execute" in sys.argv,
          cwd=Path(__file__).parents[1])
