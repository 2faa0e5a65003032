"""Write notebooks/paper_section3.ipynb from the cells below.

    python notebooks/_make_paper_section3.py             # without outputs
    python notebooks/_make_paper_section3.py --execute   # run it headless and store the outputs

Edit the cells here, not in the notebook, so that the two never drift apart.
"""

import sys
from pathlib import Path

from _nbgen import write

CELLS = [
    ("md", """# The paper's Section 3.1, reproduced: Brent's search, the cubic fit, and gradients

Tsap, Goldgof & Sarkar (PAMI 2000), Sec. 3.1: a sheet of a known material (83.76 kPa) carries a
rectangle of an unknown one (837.61 kPa by the hanging-weight test, eq. 6). The sheet is stretched
and a grid is tracked. The grid's boundary points drive the finite-element model (set P), and its
interior points guide the search (set Q). With the rectangle located by the first, uniform model,
its modulus is searched over 41.88-1591.44 kPa (half to twenty times the background) with Brent's
method on the error eq. (1), starting from the deliberately bad middle points b = 118.80 and
b = 1256.40 kPa, at tolerance 0.01 (Tables 1-3). After that the notebook shows the cubic-fit
speed-up (Fig. 9), the strain maps as the modulus changes (Fig. 8), and the same unknown
found with exact gradients.

The measurements here are synthetic. A larger sheet is solved on a conforming mesh of quadratic
triangles, sampled on a 10 mm grid, and Gaussian noise of 0.02 mm is added. The inversion uses
another mesh, so nothing can hit 837.61 exactly."""),
    ("code", """import time
import numpy as np
import matplotlib.pyplot as plt
import jaxfem as jf
from examples.paper.experiment import (BACKGROUND, BRACKET, INCLUSION, MIDDLE_POINTS, NAME, EmbeddedRectangle, PaperExperiment, format_rows, solves_to_reach)

t0 = time.perf_counter()
ex = PaperExperiment(EmbeddedRectangle())          # noise 0.02 mm, 2 frames, 10 mm grid
obs = ex.bundle.observations
print({role: int((obs.roles == role).sum()) for role in ("boundary", "guide", "validate")},
      "points;", ex.model.mesh.n_cells, ex.model.mesh.element, "cells")"""),
    ("code", """ax = jf.plot.cell_map(ex.model.mesh, ex.model.mesh.regions, cmap="Pastel1", label="region",
                     title="inversion mesh, rectangle and tracked grid")
for role, style in (("boundary", "ks"), ("guide", "bo"), ("validate", "r^")):
    p = obs.reference[obs.roles == role]
    ax.plot(p[:, 0], p[:, 1], style, ms=4, label=role)
ax.legend(loc="upper right", fontsize=7);"""),
    ("md", """## Tables 1 and 2: Brent's method from both middle points

Each row is one Brent run: the tolerance, the recovered modulus, the number of steps (forward
solves of both frames), and the distance to the ground truth."""),
    ("code", """for k, b in enumerate(MIDDLE_POINTS, start=1):
    print(f"Table {k}: b = {b:.2f} kPa (ground truth {INCLUSION} kPa)")
    print(format_rows(ex.tolerance_table(b, tolerances=(0.1, 0.01, 0.001))), end="\\n\\n")"""),
    ("md", """## Table 3: the iterations for b = 1256.40 kPa, tolerance 0.01

The first steps are golden-section steps; once three good points exist, the steps are mostly
parabolic (eq. 2), as in the paper."""),
    ("code", """brent = {b: ex.brent(b) for b in MIDDLE_POINTS}
brent[1256.40].table()
print(brent[1256.40])"""),
    ("md", """## The cubic fit (Fig. 9) and the speed-up

Four points spread over the bracket define a cubic. Its minimum becomes the middle point of a
narrow bracket, one background modulus either side, and Brent finishes there at tolerance 0.001.
The paper reports 838.38 kPa in four Brent steps. One or two parabolas fit the error curve badly,
because it is steep on the soft side and flat on the stiff side; a cubic fits it well."""),
    ("code", """cubic = ex.cubic()
cubic.table()
grid = np.linspace(*BRACKET, 25)
curve = ex.error_curve(grid)
fit_x = np.array([row[NAME] for row in cubic.history[:4]])
fit_e = np.array([row["error"] for row in cubic.history[:4]])
cubic_poly = np.polynomial.Polynomial.fit(fit_x, fit_e, 3)
parabola = np.polynomial.Polynomial.fit(fit_x[:3], fit_e[:3], 2)
n = obs.n_frames * int((obs.roles == "guide").sum())
fig, ax = plt.subplots(figsize=(7, 4))
ax.plot(grid, curve / n, "o", label="eq. (1) per point and frame")
ax.plot(grid, cubic_poly(grid) / n, "-", label="cubic through the 4 fit points")
ax.plot(grid, parabola(grid) / n, ":", label="parabola through 3 of them")
ax.axvline(INCLUSION, color="k", ls="--", lw=1, label="ground truth")
ax.set(xlabel="modulus of the rectangle, kPa", ylabel="error per point, mm", ylim=(0, 1.2 * curve.max() / n))
ax.legend(fontsize=8);"""),
    ("md", """## Fig. 8: the strain maps as the rectangle's modulus changes

(a) is the uniform model that located the rectangle. (b) and (c) are a step down and a step up.
Going softer shows the wrong direction: the rectangle strains even more than its surroundings.
(d) is an intermediate iterate and (e) is the result. (f) lies past the minimum. As the
modulus rises, the rectangle becomes a clearly outlined area of low strain."""),
    ("code", """E_hat = brent[1256.40].values[NAME]
moduli = [BACKGROUND, 0.5 * BACKGROUND, 2 * BACKGROUND, 500.0, E_hat, BRACKET[1]]
titles = [f"({c}) {E:.1f} kPa" for c, E in zip("abcdef", moduli)]
ex.strain_figure(moduli, titles);"""),
    ("md", """## The same unknown by gradients

Levenberg-Marquardt on the log ratio starts from the uniform model. Each step costs one forward
solve of both frames plus one tangent solve per frame (the exact Jacobian by the implicit function
theorem). It minimises the noise-weighted sum of squares instead of eq. (1), so with noisy data it
converges to a slightly different value. Below, each method is measured against its own converged
value. The first call compiles the solve and its derivative, which takes tens of seconds."""),
    ("code", """lm = ex.least_squares("lm")
lm.table()
print(lm)
eq1_min = ex.brent(MIDDLE_POINTS[1], tol=1e-7).values[NAME]
runs = {"Brent b=118.80": (brent[118.80], eq1_min), "Brent b=1256.40": (brent[1256.40], eq1_min),
        "cubic + Brent": (cubic, eq1_min), "Levenberg-Marquardt": (lm, lm.values[NAME])}
fig, ax = plt.subplots(figsize=(7, 4))
for label, (r, ref) in runs.items():
    best, err, dist = None, np.inf, []
    for row in r.history:
        if row["error"] < err:
            best, err = row[NAME], row["error"]
        dist.append(abs(best - ref) / ref)
    ax.semilogy(range(1, len(dist) + 1), np.maximum(dist, 1e-7), "o-", label=label)
    print(f"{label:22s} solves to 0.1 %: {solves_to_reach(r, ref)}, in all {r.n_forward}")
ax.axhline(1e-3, color="k", ls=":", lw=1)
ax.set(xlabel="forward solves", ylabel="distance to the converged value")
ax.legend(fontsize=8);"""),
    ("md", """## Absolute or relative?

No force was measured in this bundle. For a plane-stress sheet driven by its measured boundary,
the displacements depend on modulus times thickness only through ratios. The data therefore give
only the relative elasticity E_R = (E2 b2)/(E1 b1) (eq. 8): E and the thickness are confounded.
The library says so rather than returning a number. With a measured force (forces.csv) it also
fits the background (`refine.diagnosis.forces.fit_region_moduli`)."""),
    ("code", """from refine.exceptions import IdentifiabilityError
from refine.diagnosis.forces import ForcedObjective
print(f"relative elasticity of the rectangle: {lm.values['inclusion_relative_elasticity']:.3f} "
      f"(truth {INCLUSION / BACKGROUND:.3f})")
try:
    ForcedObjective(ex.model, ex.param)
except IdentifiabilityError as err:
    print("absolute modulus:", err)
print(f"notebook ran in {time.perf_counter() - t0:.0f} s")"""),
]


if __name__ == "__main__":
    write(CELLS, Path(__file__).with_name("paper_section3.ipynb"), execute="--execute" in sys.argv,
          cwd=Path(__file__).parent)
