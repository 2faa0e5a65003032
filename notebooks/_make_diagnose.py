"""Write notebooks/diagnose.ipynb (without outputs) from the cells below.

    python notebooks/_make_diagnose.py
"""

from pathlib import Path

import sys

from _nbgen import write

CELLS = [
    ("md", """# Diagnosis: what is the initial model getting wrong?

A sheet region of 100 x 60 mm is tracked on a grid while the sheet is pulled. The initial model says
the sheet is uniform. Something is hidden in it; the diagnosis must show where the uniform model
fails, decide whether the failure is more than noise, name the cause, fit it, and measure the gain
on validation points held out of every fit.

Edit the cell below to hide something else: `cause` is one of `"none"`, `"stiffer-region"`,
`"softer-region"`, `"hole"`, `"two-regions"`, `"rectangle"`; or build a `Truth` by hand. The data
come from a finer quadratic mesh of a larger sheet, with noise, so the inversion never sees its own
discretisation. To diagnose your own measurements, read them with `refine.bundle.read_bundle`."""),
    ("code", """import numpy as np
from IPython.display import Image, display
import jaxfem as jf
import refine
from refine.demo_data import Truth, Inclusion, random_truth, synthetic_bundle
from refine.diagnosis import figures, html

cause, seed = "stiffer-region", 4
truth = random_truth(np.random.default_rng(seed), cause)
# or, by hand: truth = Truth(inclusions=(Inclusion(jf.Ellipse(60, 40, 8, 5, 0.3), ratio=5.0),))
bundle = synthetic_bundle(truth, seed=seed, spacing=5.0, noise=0.02, fractions=(0.5, 1.0))
obs = bundle.observations
print(truth)
print({r: int((obs.roles == r).sum()) for r in ("boundary", "guide", "validate")}, "points,", obs.n_frames, "frames")"""),
    ("md", "## Show, decide, name, extend, measure"),
    ("code", """diagnosis = refine.diagnose(bundle)  # the entry point for 2D and 3D bundles alike
d = diagnosis.result  # the 2D diagnosis itself: its fits, its figures
print()
print(diagnosis.summary())"""),
    ("md", """The strain the tracked points themselves show (left: per triangle of their Delaunay
triangulation, no model) beside the uniform model's and the refined model's: the uniform model
already hints at the cause (the paper reads abnormality from it: a stiffer inclusion is a pocket
of low strain, a hole one of high strain), and a model that explains the data draws the measured
pattern. The residual arrows show where the uniform model misses the measured points; the
localisation field (a modulus per cell fitted by adjoint gradients with total-variation
smoothing) shows where, and its segmentation seeds the parametric fit of the region. The figures
are matplotlib Figures (`figures.all_figures(d)`); here they are shown as PNG."""),
    ("code", """U = figures.equilibria(d)  # the initial and refined models solved in every frame, once
figs = figures.all_figures(d, U)
for key in ("strain_before_after", "residuals", "regions"):
    display(Image(html.figure_png(figs[key], dpi=80)))"""),
    ("md", """`diagnosis.write` writes everything a person or ParaView reads: `report.html` (one page with
the figures embedded), `report.json` (with the settings and provenance), the figures as PNG, and
ParaView series (`paraview/*.pvd`: the initial and refined model frame by frame, the points with
their residuals, the measured strain), and `refined/` (a bundle whose initial model is the one found)."""),
    ("code", """import json
out = diagnosis.write("diagnose-out")
print(sorted(p.relative_to(out.parent).as_posix() for p in out.parent.rglob("*") if p.suffix != ".vtu"))
print(json.loads(out.read_text())["provenance"]["settings"])"""),
    ("md", "## Compare with the truth"),
    ("code", """for f in diagnosis.findings:  # report.json's findings (schema 2: the same fields in 2D and 3D)
    print(f["cause"], f["centroid"] or "", "relative elasticity", f["relative_elasticity"])
for inc in truth.inclusions:
    print("truth:", inc.cause, (round(inc.shape.cx, 2), round(inc.shape.cy, 2)), "ratio", round(inc.ratio, 3))
for h in truth.holes:
    print("truth: hole", (round(h.cx, 2), round(h.cy, 2)), "area", round(h.area, 1))
print("hypotheses tried:")
for f in d.tried:
    print("  ", f.describe(), "BIC", round(f.bic))"""),
]


if __name__ == "__main__":
    write(CELLS, Path(__file__).with_name("diagnose.ipynb"), execute="--execute" in sys.argv)
