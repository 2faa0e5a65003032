"""Write the command-line tutorials, one notebook per command: notebooks/command_NAME.ipynb.

    python notebooks/_make_commands.py                       # all, without outputs
    python notebooks/_make_commands.py --execute             # all, run headless with their outputs
    python notebooks/_make_commands.py --execute demo batch  # only these

Each runs the command exactly as typed in a shell, through ``refine.cli.main.main([...])`` (the
same argument list; ``nonrigid`` prints the same), on data it makes itself. ``nonrigid track`` and
``nonrigid diagnose`` have their own walk-throughs (tracking.ipynb, diagnose.ipynb).
Edit the cells here, not in the notebooks, so that the two never drift apart.
"""

import sys
from pathlib import Path

from _nbgen import write

SETUP = """import tempfile
from pathlib import Path

import numpy as np
from IPython.display import Image, display

from refine.cli.main import main  # main(["simulate", B, "--out", S]) is `nonrigid simulate B --out S`

work = Path(tempfile.mkdtemp(prefix="nonrigid-"))"""

SHEET = """from refine.bundle import write_bundle
from refine.demo_data import random_truth, synthetic_bundle

def sheet(cause, seed, spacing=10.0):
    \"\"\"A synthetic 100 x 60 mm sheet hiding ``cause``, solved on a finer mesh than any fit's, plus noise.\"\"\"
    truth = random_truth(np.random.default_rng(seed), cause)
    return truth, synthetic_bundle(truth, seed=seed, spacing=spacing, noise=0.02, fractions=(0.5, 1.0))"""

NOTEBOOKS = {
    "import": [
        ("md", """# `nonrigid import`: another DIC code's results as a bundle

`nonrigid import --format dice|csv --scale MM_PER_UNIT EXPORT... --out BUNDLE` reads DICe solution
files or a plain CSV (`frame,x,y,ux,uy`, or one file per frame with `x,y,ux,uy`) and writes a
measurement bundle (`docs/measurement-bundle.md`): the points, their displacements per frame, their
roles (boundary points drive the model, guide points steer the fits, validation points are held
out) and a first model for you to check. Here a smooth stretch of a grid of points is written as
such a CSV and imported."""),
        ("code", SETUP + """

x, y = np.meshgrid(np.arange(0.0, 101.0, 5.0), np.arange(0.0, 61.0, 5.0))
X = np.column_stack([x.ravel(), y.ravel()])
rows = ["frame,x,y,ux,uy"]
for frame, stretch in enumerate((0.05, 0.10), start=1):
    u = np.column_stack([stretch * X[:, 0], -0.3 * stretch * (X[:, 1] - 30.0)])
    rows += [f"{frame},{a:.3f},{b:.3f},{c:.5f},{d:.5f}" for (a, b), (c, d) in zip(X, u)]
(work / "displacements.csv").write_text("\\n".join(rows) + "\\n")
print(len(rows) - 1, "rows, the first:", *rows[:3], sep="\\n")"""),
        ("md", "The command (the CSV is in mm already: `--scale 1`):"),
        ("code", """bundle_dir = work / "bundle"
status = main(["import", "--format", "csv", "--scale", "1", str(work / "displacements.csv"), "--out", str(bundle_dir)])
print("exit status", status)
print(sorted(p.name for p in bundle_dir.iterdir()))"""),
        ("md", """`experiment.toml` holds the domain (the outline of the points), the roles' rule and the initial
model, a guess to check and edit before `simulate` or `diagnose`:"""),
        ("code", """print((bundle_dir / "experiment.toml").read_text())"""),
        ("code", """import matplotlib.pyplot as plt
from refine.bundle import read_bundle

obs = read_bundle(bundle_dir).observations
fig, ax = plt.subplots(figsize=(6, 3.6))
for role, style in (("boundary", "ks"), ("guide", "bo"), ("validate", "r^")):
    p = obs.reference[obs.roles == role]
    ax.plot(p[:, 0], p[:, 1], style, ms=4, label=f"{role} ({len(p)})")
ax.set(aspect="equal", xlabel="x, mm", ylabel="y, mm", title="the imported points and their roles")
ax.legend(fontsize=7, loc="upper right");"""),
        ("md", """A DICe export is read the same way (`--format dice --scale MM_PER_PX DICE_OUTPUT_DIR`); the scale
turns its pixels into mm. Next: `nonrigid simulate` (`command_simulate.ipynb`) and
`nonrigid diagnose` (`diagnose.ipynb`) on the bundle."""),
    ],
    "simulate": [
        ("md", """# `nonrigid simulate`: the initial model driven by the measured boundary

`nonrigid simulate BUNDLE --out DIR` moves the bundle's initial model by its measured boundary
points, predicts every other point, and writes the predicted displacements, a strain map per frame
and ParaView files. Where the prediction misses the measurement is what `nonrigid diagnose` then
explains. The bundle here is a synthetic sheet hiding a stiffer region that its initial model,
uniform, does not know of."""),
        ("code", SETUP + "\n\n" + SHEET + """

truth, bundle = sheet("stiffer-region", seed=4, spacing=5.0)
write_bundle(work / "bundle", bundle)
print(truth)"""),
        ("code", """status = main(["simulate", str(work / "bundle"), "--out", str(work / "sim")])
print("exit status", status)
print(sorted(p.name for p in (work / "sim").iterdir()))"""),
        ("md", """The strain map of the last frame: the uniform model strains evenly where the sheet, stiffer
inside the hidden region, does not."""),
        ("code", """last = sorted((work / "sim").glob("strain_frame*.png"))[-1]
display(Image(filename=str(last), width=560))"""),
        ("md", "The predicted displacements against the measured ones, point by point:"),
        ("code", """import csv
from refine.bundle import read_bundle

obs = read_bundle(work / "bundle").observations
with open(work / "sim" / "displacements.csv", newline="") as fh:
    rows = list(csv.DictReader(fh))
print(rows[0].keys())
print(len(rows), "rows;", obs.n_points, "points x", obs.n_frames, "frames measured")"""),
        ("md", """Open `DIR/paraview/model.pvd` and `points.pvd` in ParaView to step through the frames. Next:
`nonrigid diagnose` (`diagnose.ipynb`) names what the model gets wrong."""),
    ],
    "demo": [
        ("md", """# `nonrigid demo`: a hidden inclusion, end to end

`nonrigid demo [--out DIR] [--seed N]` hides a stiffer disc in a synthetic sheet, simulates the
uniform initial model and diagnoses it, and prints what was found next to the truth: the whole
pipeline in one command, on data from a finer mesh than the fit's, with noise."""),
        ("code", SETUP),
        ("code", """status = main(["demo", "--out", str(work / "demo"), "--seed", "3"])
print("exit status", status)"""),
        ("md", "What it wrote: the bundle, the simulation and the diagnosis' report."),
        ("code", """for p in sorted((work / "demo").rglob("*")):
    if p.is_file() and "paraview" not in p.parts:
        print(p.relative_to(work / "demo"))"""),
        ("code", """for png in sorted((work / "demo").rglob("regions.png")) + sorted((work / "demo").rglob("strain_before_after.png")):
    display(Image(filename=str(png), width=640))"""),
        ("md", """`report.html` beside those figures is the page to read (finding, strain maps, residuals,
hypotheses, errors, settings). The diagnosis step by step (`diagnose.ipynb`) explains each part."""),
    ],
    "batch": [
        ("md", """# `nonrigid batch diagnose`: many bundles on Dask

`nonrigid batch diagnose BUNDLES... --out DIR` diagnoses every bundle on a Dask cluster (the
`batch` extra: `pip install -e ".[batch]"`): a local cluster of worker processes by default, or a
running one with `--scheduler tcp://HOST:8786`. Each bundle's report goes to `DIR/<bundle name>/`
and its row to `DIR/results.jsonl` as soon as it is done; running the command again skips the
bundles already done, and a bundle that fails is recorded with its error while the batch goes on.
Here: two small synthetic sheets (one hides a stiffer region, one nothing) and a third folder that
is no bundle at all."""),
        ("code", SETUP + "\n\n" + SHEET + """

bundles = []
for name, cause, seed in (("stiff", "stiffer-region", 4), ("plain", "none", 5)):
    truth, bundle = sheet(cause, seed)
    bundles.append(str(write_bundle(work / name, bundle)))
    print(name, truth)
(work / "broken").mkdir()
bundles.append(str(work / "broken"))"""),
        ("code", """status = main(["batch", "diagnose", *bundles, "--out", str(work / "reports"), "--workers", "1", "--quiet"])
print("exit status", status)"""),
        ("md", """The exit status is 1 because a bundle failed (0 when every bundle was diagnosed); the others'
reports are written all the same. One row per bundle (the broken one with its error), and the
batch's summary:"""),
        ("code", """import json

for line in (work / "reports" / "results.jsonl").read_text().splitlines():
    row = json.loads(line)
    print({k: row.get(k) for k in ("bundle", "cause", "gain", "seconds", "error")})
print((work / "reports" / "summary.txt").read_text())
if (work / "reports" / "batch.png").exists():
    display(Image(filename=str(work / "reports" / "batch.png"), width=560))"""),
        ("md", """From Python the same is `refine.batch.diagnose_many` (in a script, under
`if __name__ == "__main__":`, since the workers are spawned processes)."""),
    ],
    "follow": [
        ("md", """# `nonrigid follow`: a sequence seen without correspondences

`nonrigid follow BUNDLE --out DIR` follows a sheet seen in every frame only as unlabelled samples
of its outline and surface (the bundle's `clouds.csv`; fresh samples each frame, no point seen
twice). The model, clamped at its left side and moved by a grip at its right side, predicts each
frame and is fitted to its cloud; where the prediction fails beyond the noise it is refined (a
modulus field, then a region). It writes every model node's position in every frame. The sequence
here hides a stiff inclusion."""),
        ("code", SETUP + """

from refine.bundle import write_bundle
from examples.synthetic.clouds import cloud_sequence, random_cloud_truth

seed, noise = 21, 0.015
truth = random_cloud_truth(np.random.default_rng(seed), "stiffer-region", (0.0, 0.0, 100.0, 50.0))
bundle, hidden = cloud_sequence(truth, seed=seed, domain=(0.0, 0.0, 100.0, 50.0), h=3.0, noise=noise)
write_bundle(work / "clouds", bundle)
print(truth.inclusion)
print([len(c) for c in bundle.clouds.points], "points per frame")"""),
        ("code", """import matplotlib.pyplot as plt

fig, axes = plt.subplots(1, 2, figsize=(9, 2.6), sharey=True)
for ax, k in zip(axes, (0, len(bundle.clouds.points) - 1)):
    c = bundle.clouds.points[k]
    ax.plot(c[:, 0], c[:, 1], ".", ms=1.5)
    ax.set(aspect="equal", title=f"frame {k}: {len(c)} unlabelled points")"""),
        ("code", """status = main(["follow", str(work / "clouds"), "--out", str(work / "follow"), "--noise", str(noise)])
print("exit status", status)"""),
        ("code", """import json

summary = json.loads((work / "follow" / "follow.json").read_text())
print("refined at frames:", summary["refinements"])
for f in summary["findings"]:
    print(f["cause"], "at", np.round(f["centroid"], 1), "(hidden:", (round(truth.inclusion.shape.cx, 1),
          round(truth.inclusion.shape.cy, 1)), ")")
display(Image(filename=str(work / "follow" / "errors.png"), width=560))"""),
        ("md", """`correspondences.csv` holds every node's position per frame (`frame, node, x, y, ...`). The
paper's Hausdorff force method is in `refine.correspond` as the baseline."""),
    ],
}


if __name__ == "__main__":
    here = Path(__file__).resolve().parent
    chosen = [a for a in sys.argv[1:] if not a.startswith("--")] or list(NOTEBOOKS)
    for name in chosen:
        write(NOTEBOOKS[name], here / f"command_{name}.ipynb", execute="--execute" in sys.argv, cwd=here)
