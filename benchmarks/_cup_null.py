"""What the SOUND cup holder's null test rejects (issue 23 (a), benchmarks/README.md's diagnose3d
section): the local model of the bottom (refine.solid.diagnose.local_recipe) against the fine
data of a cup holder without a hole, one difference between data and model at a time.

Per variant (``--h`` the local model's element size, ``--layers``) and data (``clean``: the
data's noise-free solve; ``noisy``: with the benchmark bundle's very noise draw), one initial
solve of the local model and:

- ``null_ratio``: the null test's misfit over its expectation (refine.solid.initial, with the
  drive's noise propagated by 8 samples; noisy data only);
- ``chi2_per``: chi2 per guide residual at the noise (noise alone: 1), at the experiment's
  modulus and with the closed-form best uniform modulus (``chi2_per_E``, ``modulus``);
- the misfit's RMS (mm) by ring of radius (where it lies: the driven ring's edge, the middle);
- ``--floor``: the 3D diagnosis's null test on the global model (refine.solid.null_level.global_null:
  its ratio, p-value, fitted modulus and discretisation error).

Writes JSON lines to --out.

    python benchmarks/_cup_null.py --seed 4 --h 1.2 0.85 --data clean noisy
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.append(str(HERE))

import numpy as np  # noqa: E402

from _cup_bias import data, write_points  # noqa: E402
from _timing import loadavg  # noqa: E402


def bundle_noise(seed: int, hole, spacing: float, n_frames: int, noise: float, shape) -> np.ndarray:
    """The benchmark bundle's own noise draw (refine.synthetic.cup.cup_bundle's rng after the points)."""
    from refine.synthetic.cup import CupGeometry, _points

    rng = np.random.default_rng(seed)
    _points(CupGeometry(), hole, spacing, rng)
    return rng.normal(0.0, noise, (n_frames, *shape))


def local_row(bundle_root: Path, h: float, layers, sigma: float, noisy: bool, floor: bool) -> dict:
    """The local model's misfit on the bundle at ``bundle_root`` (see the module); ``floor``: the
    local model's own error (refine.solid.null_level.model_floor: the wall's and the global
    mesh's shares) and the null test with it, the global models' misfits beside it."""
    from dataclasses import replace

    from refine.bundle.io import read_bundle
    from refine.solid.diagnose import SolidConfig, local_recipe
    from refine.solid.initial import checked_baseline
    from refine.solid import null_level

    bundle = read_bundle(bundle_root)
    _, local, _ = local_recipe(bundle, SolidConfig(h=h))
    local = replace(local, layers=layers)
    t0 = time.perf_counter()
    model, _ = local.model()
    obs = local.obs
    guide = obs.roles == "guide"
    out = {"cells": int(model.mesh.n_cells), "dofs": int(model.problem.n_dofs), "guide": int(guide.sum())}
    if noisy:
        base, null = checked_baseline(model, obs, sigma)
        pred = base.predicted
        out.update(null_ratio=null.ratio, null_propagation=null.propagation)
    else:
        pred = np.asarray(model.predict(model.params()))
    out["solve_s"] = time.perf_counter() - t0
    out.update(misfit(obs, pred, guide, sigma))
    if floor:
        t0 = time.perf_counter()
        null, level = null_level.global_null(bundle, local, guide, sigma)
        out["global_null"] = {**level, "ratio": null.ratio, "p_value": null.p_value, "dof": null.dof,
                              "seconds": time.perf_counter() - t0}
    return out


def misfit(obs, pred, guide, sigma: float) -> dict:
    """chi2 per guide residual at ``sigma`` at the experiment's modulus and at the best uniform
    one (closed form), and the misfit's RMS (mm) by ring of radius, component and frame."""
    from refine.measures import Residuals

    out = {}
    at = Residuals.at(obs.displacements, guide, sigma)
    r0 = at(pred)
    v = at(2 * pred) - r0
    s = 1 - (r0 @ v) / max(v @ v, 1e-300)
    out.update(chi2_per=float(r0 @ r0) / len(r0), chi2_per_E=float((r0 + (s - 1) * v) @ (r0 + (s - 1) * v)) / len(r0),
               modulus=float(1 / s))
    R = (obs.displacements - pred)[:, guide]  # (frames, m, 3)
    r = np.hypot(*obs.reference[guide, :2].T)
    edges = [0.0, 2.0, 4.0, 6.0, 7.0, 8.0]
    out["rms_by_radius_mm"] = {f"{a:g}-{b:g}": float(np.sqrt(np.nanmean(R[:, (r >= a) & (r < b)] ** 2)))
                               for a, b in zip(edges[:-1], edges[1:]) if ((r >= a) & (r < b)).any()}
    out["rms_by_component_mm"] = [float(np.sqrt(np.nanmean(R[..., k] ** 2))) for k in range(3)]
    out["rms_by_frame_mm"] = [float(np.sqrt(np.nanmean(R[f] ** 2))) for f in range(len(R))]
    out["data_rms_mm"] = float(np.sqrt(np.nanmean(obs.displacements[:, guide] ** 2)))
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seed", type=int, default=4)
    p.add_argument("--hole", action="store_true", help="the seed's hole (default: a sound cup holder)")
    p.add_argument("--h", type=float, nargs="+", default=[1.2], help="the local model's element sizes (mm)")
    p.add_argument("--layers", type=int, default=None)
    p.add_argument("--data", nargs="+", default=["clean", "noisy"])
    p.add_argument("--floor", action="store_true", help="the local model's own error (the global models) too")
    p.add_argument("--h-data", type=float, default=0.8)
    p.add_argument("--spacing", type=float, default=0.6)
    p.add_argument("--noise", type=float, default=0.005)
    p.add_argument("--forces", type=float, nargs="+", default=[1.0, 2.0, 3.0, 4.0])
    p.add_argument("--out", type=Path, default=HERE / "results" / "cup_null.jsonl")
    args = p.parse_args()
    cache = Path(tempfile.gettempdir()) / "cup_bias_cache"
    cache.mkdir(exist_ok=True)
    g, hole, X, roles, U = data(args.seed, args.h_data, args.spacing, args.forces, cache, sound=not args.hole)
    for kind in args.data:
        Un = U + bundle_noise(args.seed, hole, args.spacing, len(args.forces), args.noise, X.shape) \
            if kind == "noisy" else U
        with tempfile.TemporaryDirectory() as tmp:
            root = write_points(g, X, roles, Un, args.forces, args.noise, Path(tmp))
            for h in args.h:
                row = {"seed": args.seed, "hole": args.hole, "data": kind, "h": h, "layers": args.layers,
                       "h_data": args.h_data, **local_row(root, h, args.layers, args.noise, kind == "noisy", args.floor),
                       "load": loadavg()}
                print(json.dumps(row), flush=True)
                with args.out.open("a") as fh:
                    fh.write(json.dumps(row) + "\n")


if __name__ == "__main__":
    main()
