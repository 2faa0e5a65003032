"""The range-image front end: tracked 3D points and clouds of a compressed cup holder.

The range-image front end's accuracy: a cup holder compressed by jaxfem (fine tet10 mesh, a hidden
hole in its bottom at a random place and size under each seed) rendered from below as intensity +
range images (examples.cup_holder.views), tracked by ``nonrigid track --range``; the tracked 3D
points against the painted crossings' true positions, and the clouds against the true surface, for
both cameras, the bilinear and the quadratic lookup, and range noise 0.02 / 0.05 / 0.1 mm. Clouds
are judged by the exact distance of each point to the deformed surface's triangles.

    python -m benchmarks range_front                 # 2 seeds (~5 min on 2 cores)
    python -m benchmarks range_front --seeds 1 --quick

Writes benchmarks/results/range_front.json (with ``targets``) and range_front.png.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np


import jaxfem as jf  # noqa: E402
from refine.cli.track import track  # noqa: E402
from refine.cli.track_range import RangeOptions  # noqa: E402
from examples.cup_holder.views import (CupScene, compressed_cup, crossing_errors, cup_camera,  # noqa: E402
                                        painted_crossings, render_cup, write_frames)
from examples.synthetic.solid_render import surface_distance  # noqa: E402
from benchmarks._cli import QUICK, quick  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results"


def random_hole(rng):
    """An elliptic hole in the floor (as tests/test_cup_holder.random_hole)."""
    rx, ry = rng.uniform(2.0, 3.5), rng.uniform(1.5, 2.5)
    r, phi = rng.uniform(0.0, 8.0 - rx - 1.5), rng.uniform(0, 2 * np.pi)
    return jf.Ellipse(r * np.cos(phi), r * np.sin(phi), rx, ry, rng.uniform(0, np.pi))


def cloud_error(cloud, cup, u) -> tuple[float, float]:
    """RMS and largest distance of a cloud from the true deformed surface, mm."""
    distance = surface_distance(cloud, cup.mesh.nodes, cup.mesh.boundary_facets(), u)
    return float(np.sqrt(np.mean(distance ** 2))), float(distance.max())


def run_seed(seed, cameras, noises, orders, h):
    """One solve of a cup holder with a random hole; rendered and tracked per camera and noise."""
    rng = np.random.default_rng(seed)
    base = CupScene(hole=random_hole(rng))
    t = time.perf_counter()
    cup, U = compressed_cup(base, forces=(1.5, 3.0), h=h)
    solve = time.perf_counter() - t
    rows = []
    for camera_model in cameras:
        for noise in noises:
            scene = replace(base, camera=cup_camera(camera_model), depth_noise=noise)
            with tempfile.TemporaryDirectory() as d:
                rows += track_case(scene, cup, U, seed, Path(d), orders, {"solve": solve})
    return rows


def track_case(scene, cup, U, seed, work, orders, seconds):
    t = time.perf_counter()
    views = render_cup(scene, cup, U, seed=seed)
    seconds = {**seconds, "render_3_frames": time.perf_counter() - t}
    truth = painted_crossings(scene, cup, U)
    images, ranges = write_frames(views, work / "frames")
    mesh = work / "cup.vtu"
    jf.write_vtu(mesh, CupScene().mesh(3.0).mesh)
    rows = []
    for order in orders:
        t = time.perf_counter()
        bundle = track(images, work / f"B{order}", ranges=RangeOptions(ranges, scene.camera, mesh, order=order,
                                                                       clouds=True, cloud_spacing=0.5), quiet=True)
        obs = bundle.observations
        err = crossing_errors(obs.reference, obs.displacements, truth)
        rows.append({"seed": seed, "camera": scene.camera.model, "noise": scene.depth_noise, "order": order,
                     "points": obs.n_points, **err,
                     "cloud_rms": [cloud_error(c, cup, u)[0] for c, u in zip(bundle.clouds.points, [None, *U])],
                     "cloud_max": [cloud_error(c, cup, u)[1] for c, u in zip(bundle.clouds.points, [None, *U])],
                     "cloud_points": [len(c) for c in bundle.clouds.points],
                     "lift": float(np.abs(truth[-1][:, 2] - truth[0][:, 2]).max()),
                     "seconds": {**seconds, "track": time.perf_counter() - t}})
        print(json.dumps({k: rows[-1][k] for k in ("seed", "camera", "noise", "order", "points", "rms_xy",
                                                    "rms_z", "rms_uz", "cloud_rms")}), flush=True)
    return rows


def targets(rows):
    """Per row: tracked positions and clouds within the depth noise (the brief's ~noise)."""
    out = {}
    for r in rows:
        key = f"{r['camera']}-order{r['order']}-noise{r['noise']}-seed{r['seed']}"
        z, c = max(r["rms_z"]), max(r["cloud_rms"])
        out[key] = {"rms_z_over_noise": z / r["noise"], "cloud_rms_over_noise": c / r["noise"],
                    "rms_xy_mm": max(r["rms_xy"]), "pass": bool(z <= r["noise"] and c <= r["noise"]
                                                                 and max(r["rms_xy"]) < 0.02)}
    return out


def plot(rows, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    for (camera, order), marker in zip([(c, o) for c in ("orthographic", "perspective") for o in (1, 2)], "osD^"):
        sel = [r for r in rows if r["camera"] == camera and r["order"] == order]
        if sel:
            ax[0].plot([r["noise"] for r in sel], [max(r["rms_z"]) for r in sel], marker, label=f"{camera}, order {order}")
    cl = [r for r in rows if r["order"] == rows[0]["order"]]
    ax[1].plot([r["noise"] for r in cl], [max(r["cloud_rms"]) for r in cl], "o", label="clouds (0.5 mm cells)")
    for a in ax:
        a.plot([0, 0.11], [0, 0.11], "k--", lw=0.8, label="= noise")
        a.set_xlabel("range noise (mm)")
        a.legend(fontsize=7)
    ax[0].set_ylabel("tracked points: RMS depth error (mm)")
    ax[1].set_ylabel("clouds: RMS distance to the surface (mm)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main(argv=None) -> int:
    argv = quick(argv, ["--quick", "--out", str(QUICK / "range_front.json")])
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seeds", type=int, default=2)
    p.add_argument("--quick", action="store_true", help="noise 0.05 only, both cameras, h = 2.5")
    p.add_argument("--out", default=str(RESULTS / "range_front.json"))
    args = p.parse_args(argv)
    noises = (0.05,) if args.quick else (0.02, 0.05, 0.1)
    h = 2.5 if args.quick else 2.0
    rows, t0 = [], time.perf_counter()
    for seed in range(args.seeds):
        rows += run_seed(seed, ("orthographic", "perspective"), noises, (1, 2), h)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    result = {"rows": rows, "targets": targets(rows), "seconds": time.perf_counter() - t0,
              "load": os.getloadavg(), "h_mm": h}
    out.write_text(json.dumps(result, indent=1))
    plot(rows, out.with_suffix(".png"))
    print(f"wrote {out}; targets pass: {sum(t['pass'] for t in result['targets'].values())}/{len(result['targets'])}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
