"""Write notebooks/cup_holder.ipynb from the cells below (executed with ``--execute``).

    python notebooks/_make_cup_holder.py --execute
"""

import sys
from pathlib import Path

from _nbgen import write

CELLS = [
    ("md", """# The foam cup holder's hidden hole (the paper's Sec. 4)

A foam cup holder (a short thick-walled cylinder with a bottom, neo-Hookean, nu 0.4) has a hole in
its bottom that the modeller's 3D model does not have. The cup holder is held at its rim and its
bottom is pushed up by a measured force; a camera with a range scanner below sees the painted
bottom move. The paper's two models: a **local model** of the observed bottom finds where the
strain is abnormally high, cuts a hole there and varies its size and place; the found hole goes
into the **global model** of the whole cup holder, which predicts the held-out points.

The data here come from `examples.cup_holder.synthetic`: the cup holder with a hole drawn at random under a
seed, solved on a finer tet10 mesh than the inversion uses, sampled at the crossings of a painted
grid with noise 0.01 mm (the end-to-end path from rendered intensity + range images through
`nonrigid track --range` is in `tests/test_solid_diagnosis.py` and `benchmarks/diagnose3d.py`).
The whole run takes several minutes on 2 cores (tests/test_notebooks.py runs it with the slow tests)."""),
    ("code", """%matplotlib inline
import json, tempfile
from pathlib import Path
import numpy as np
import matplotlib.pyplot as plt
import jaxfem as jf
from refine.bundle.io import read_bundle
from examples.cup_holder.synthetic import CupGeometry, random_hole, write_cup_bundle

geometry, seed = CupGeometry(), 1
truth = random_hole(geometry, seed)
work = Path(tempfile.mkdtemp())
root = write_cup_bundle(work / "cup", geometry=geometry, hole=truth, h_data=1.2, h_model=2.0, noise=0.01, seed=seed)
bundle = read_bundle(root)
obs = bundle.observations
print(f"hidden hole: centre ({truth.cx:.2f}, {truth.cy:.2f}) mm, semi-axes ({truth.rx:.2f}, {truth.ry:.2f}) mm, "
      f"area {truth.area:.2f} mm2; {obs.n_points} points, {obs.n_frames} frames, forces {obs.forces.on('back')[:, 2]} N")"""),
    ("md", """## The measurements in 3D

The points on the bottom's outer face (the camera's view), the outer wall and the rim (held by the
fixture), coloured by their displacement along the axis in the last frame. The hole leaves a gap in
the painted grid; the bottom bulges into the cup."""),
    ("code", """X, U = obs.reference, obs.displacements[-1]
fig = plt.figure(figsize=(11, 4.5))
ax = fig.add_subplot(1, 2, 1, projection="3d")
sc = ax.scatter(*(X + U).T, c=U[:, 2], cmap="viridis", s=6)
ax.set_xlabel("x (mm)"); ax.set_ylabel("y (mm)"); ax.set_zlabel("z (mm)")
ax.set_title("points, last frame (deformed)")
fig.colorbar(sc, ax=ax, shrink=0.6, label="u_z (mm)")
ax2 = fig.add_subplot(1, 2, 2)
on = np.abs(X[:, 2]) < 1e-6
for role, m in (("boundary", "s"), ("guide", "o"), ("validate", "^")):
    k = on & (obs.roles == role)
    ax2.scatter(X[k, 0], X[k, 1], c=U[k, 2], cmap="viridis", marker=m, s=14, label=role)
t = np.linspace(0, 2 * np.pi, 200)
ax2.plot(*np.c_[truth.to_curve(np.c_[truth.cx + 10 * np.cos(t), truth.cy + 10 * np.sin(t)])].T, "r-", label="hidden hole")
ax2.set_aspect("equal"); ax2.legend(fontsize=7, loc="lower right"); ax2.set_title("bottom face: roles, u_z")
plt.tight_layout()"""),
    ("md", """## The diagnosis: local model, then global model

`refine.diagnose` (what `nonrigid diagnose` runs, here on a solid bundle with an observed thin wall): the
local model of the bottom slab, driven by the points under the wall and loaded by the measured
force, fails the null test; a hole is cut at the gap in the points and fitted by exact implicit
gradients through an extruded morph; the found hole is refitted in the global model of the whole
cup holder (with a uniform modulus beside it, which absorbs the coarse model's discretisation
stiffness), held by the rim's points, and both global models (without and with the hole) predict
the held-out points."""),
    ("code", """import refine
from refine.solid.write import write_paraview

diagnosis = refine.diagnose(root, out=work / "out")
d, rep = diagnosis.result, diagnosis.report()  # the cup holder's diagnosis and its report.json
f = rep["findings"][0]
off = np.hypot(f["centroid"][0] - truth.cx, f["centroid"][1] - truth.cy)
print(f"centre error {100 * off / geometry.diameter:.2f} % of the bottom's diameter, area error "
      f"{100 * (f['area'] / truth.area - 1):+.1f} % (local model alone: {100 * (f['local_model']['area'] / truth.area - 1):+.1f} %)")
print(json.dumps({k: rep[k] for k in ("cause", "held_out_gain", "seconds")}, indent=1))
print(json.dumps(rep["global"], indent=1))"""),
    ("md", """## The found hole in 3D

The local model's mesh (the bottom slab) and the global model's (the whole cup holder) with the
found hole, the truth's outline in red."""),
    ("code", """from mpl_toolkits.mplot3d.art3d import Poly3DCollection

def draw(ax, mesh, colour):
    f = mesh.boundary_facets()[:, :3]
    ax.add_collection3d(Poly3DCollection(mesh.nodes[f], facecolor=colour, edgecolor="k", linewidths=0.1, alpha=0.35))
    lo, hi = mesh.bounds()
    ax.set_xlim(lo[0], hi[0]); ax.set_ylim(lo[1], hi[1]); ax.set_zlim(lo[2], lo[2] + hi[0] - lo[0])

fig = plt.figure(figsize=(11, 5))
for k, (name, fit) in enumerate((("local model", d.chosen), ("global model", d.whole))):
    ax = fig.add_subplot(1, 2, k + 1, projection="3d")
    draw(ax, fit.model.mesh, "C0" if k == 0 else "C1")
    c = truth.to_curve(np.c_[truth.cx + 10 * np.cos(t), truth.cy + 10 * np.sin(t)])
    ax.plot(c[:, 0], c[:, 1], 0 * c[:, 0], "r-", lw=2)
    ax.set_title(f"{name}: {fit.model.mesh.n_cells} cells, {fit.shapes[0].describe()}", fontsize=8)
    ax.view_init(elev=-35, azim=-60)
plt.tight_layout()"""),
    ("md", """## ParaView files

The local model without and with the hole and the global model with it, one VTU per frame and a
PVD series each (open the `.pvd` in ParaView, "Warp By Vector" on `displacement`); the global
model with the finding is also a bundle (`out/global`: mesh.vtu and experiment.toml with
`[meta.finding]`) that `nonrigid simulate` and `nonrigid diagnose` read."""),
    ("code", """files = write_paraview(d, work / "out" / "paraview")
for name, path in files.items():
    print(name, path.relative_to(work))
print((work / "out" / "global" / "experiment.toml").read_text())"""),
]

if __name__ == "__main__":
    here = Path(__file__).resolve().parent
    write(CELLS, here / "cup_holder.ipynb", execute="--execute" in sys.argv, cwd=here)
