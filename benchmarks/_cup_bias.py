"""Controlled experiments on the cup holder's hole-area bias (issue 23, benchmarks/README.md's
diagnose3d section): the global model with the TRUE hole (or the true hole scaled in area) against
one seed of the fine bundle data, one difference between data and model switched off at a time.

Each evaluation is one forward solve of the global model (4 frames) at E = 1 followed by the
closed-form best uniform modulus (displacements under a measured force scale about as 1/E; the
factor least squares, as refine.solid.start.best_start does): chi2 per guide residual at the
noise, the fitted modulus, and the guide residuals' RMS (mm). Writes JSON lines to --out.

    python benchmarks/_cup_bias.py --seed 1 --variants clean rim_noise_off all_noise --scales 0.9 1 1.1
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.append(str(HERE))

import numpy as np  # noqa: E402

from _timing import loadavg  # noqa: E402


def data(seed: int, h_data: float, spacing: float, forces, cache: Path, sound: bool = False):
    """Points, roles and noise-free displacements of the fine bundle of ``seed`` (cached);
    ``sound``: the cup holder without a hole (the hole None)."""
    import jaxfem as jf
    from refine.synthetic.cup import CupGeometry, _points, random_hole, solve_cup

    g = CupGeometry()
    hole = None if sound else random_hole(g, seed)
    f = cache / f"cup_bias_seed{seed}{'_sound' if sound else ''}_h{h_data}_s{spacing}.npz"
    if f.exists():
        z = np.load(f)
        return g, hole, z["X"], z["roles"], z["U"]
    rng = np.random.default_rng(seed)  # as cup_bundle draws them
    X, roles = _points(g, hole, spacing, rng)
    U = solve_cup(g, hole, forces, h_data, X)
    np.savez(f, X=X, roles=roles, U=U)
    del jf
    return g, hole, X, roles, U


def noisy(U, roles, X, g, variant: str, noise: float, seed: int):
    """``U`` with noise as ``variant`` says: clean, all_noise, rim_noise_off (noise everywhere but
    the rim's boundary points)."""
    rng = np.random.default_rng(1000 + seed)
    N = rng.normal(0.0, noise, U.shape)
    if variant == "clean":
        return U.copy()
    if variant == "rim_noise_off":
        rim = np.abs(X[:, 2] - g.height) < 1e-9
        N[:, rim] = 0.0
    return U + N


def write_points(g, X, roles, U, forces, noise: float, tmp: Path) -> Path:
    """A cup-holder bundle of these points (as refine.synthetic.cup.cup_bundle writes it) in ``tmp``."""
    import jaxfem as jf
    from refine.bundle.experiment import Experiment, MeshDomain
    from refine.bundle.io import Bundle, write_bundle
    from refine.bundle.observations import Forces, Observations

    F = np.zeros((len(forces), 1, 3))
    F[:, 0, 2] = forces
    obs = Observations(np.arange(1, len(X) + 1), X, roles, U, forces=Forces(("back",), F))
    exp = Experiment(name="cup-holder", kind="solid", domain=MeshDomain("mesh.vtu"), law=g.law, E=g.E, nu=g.nu,
                     units={"length": "mm", "stress": "MPa", "force": "N"}, noise_std=noise or 0.005)
    root = tmp / "b"
    root.mkdir(parents=True, exist_ok=True)
    jf.write_vtu(root / "mesh.vtu", jf.cup_holder(g.r_in, g.r_out, g.height, g.bottom, 2.0).mesh)
    write_bundle(root, Bundle(exp, obs))
    return root


def whole_model(g, X, roles, U, forces, h: float, noise: float, tmp: Path, layers: int | None = None):
    """The diagnosis's global-model recipe (refine.solid.diagnose.refit_whole) for these data."""
    from refine.bundle.io import read_bundle
    from refine.bundle.roles import point_spacing
    from refine.solid.cup import bottom_points
    from refine.solid.diagnose import SolidConfig, local_recipe
    from refine.solid.global_model import held_by_fixture
    from refine.solid.local import Whole

    bundle = read_bundle(write_points(g, X, roles, U, forces, noise, tmp))
    _, local, _ = local_recipe(bundle, SolidConfig(h=h))
    tol = 0.05 * point_spacing(bundle.observations.reference)
    held = held_by_fixture(bundle.observations, local.shape, tol)
    on = bottom_points(local.shape, held.reference, tol)
    held = replace(held, reference=held.reference - local.shape.offset)
    whole = Whole(local.shape, local.experiment, held, local.force, h, local.linear_solver, layers)
    return whole, (held.roles == "guide") & on, held.roles == "validate"


def evaluate(whole, hole, scale: float, guide, validate, sigma: float, clamp_all: bool,
             modulus: float | None = None) -> dict:
    """One solve of the global model with ``hole`` scaled to ``scale`` x its area, the best uniform
    modulus in closed form; chi2 per guide residual (at ``sigma``) and RMS (mm); ``modulus``: the
    chi2 per residual at that modulus held (``chi2_per_held``; the prediction scaled as 1/E)."""
    import jaxfem as jf
    from refine.measures import Residuals

    k = np.sqrt(scale)
    e = jf.Ellipse(hole.cx, hole.cy, k * hole.rx, k * hole.ry, hole.angle)
    t0 = time.perf_counter()
    model, cup = whole.model(e)
    if clamp_all:
        model = clamped(whole, model, cup)
    pred = np.asarray(model.predict(model.params()))[:, :len(guide)]
    out = {"scale": scale, "driven_nodes": int(len(model.loop)),
           "rim_nodes": int(len(cup.sets["rim"])), "solve_s": time.perf_counter() - t0}
    for name, mask in (("guide", guide), ("validate", validate)):
        at = Residuals.at(whole.obs.displacements, mask, sigma)
        r0 = at(pred)
        v = at(2 * pred) - r0
        s = 1 - (r0 @ v) / max(v @ v, 1e-300)
        r = r0 + (s - 1) * v
        out[name] = {"chi2_per": float(r @ r) / len(r), "chi2_per_E1": float(r0 @ r0) / len(r0),
                     "modulus": float(1 / s), "rms_mm": float(np.sqrt(np.mean(r ** 2)) * sigma)}
        if modulus is not None:
            rh = r0 + (1 / modulus - 1) * v
            out[name]["chi2_per_held"] = float(rh @ rh) / len(rh)
    return out


def clamped(whole, model, cup):
    """``model`` with every rim node held still (the data's fixture) instead of the rim points'
    interpolated drive: a LoadedModel whose boundary points are the rim's nodes themselves (after
    the bundle's points, which keep their order; the rim's measured points drive nothing)."""
    from refine.bundle.observations import Observations
    from refine.solid.loaded import LoadedModel

    obs = whole.obs
    rim = cup.mesh.nodes[cup.sets["rim"]]
    roles = np.where(obs.roles == "boundary", "validate", obs.roles)  # out of the drive; unscored
    n = len(rim)
    U = np.zeros((obs.n_frames, n, 3))
    o2 = Observations(np.r_[obs.ids, obs.ids.max() + 1 + np.arange(n)], np.vstack([obs.reference, rim]),
                      np.r_[roles, np.full(n, "boundary")], np.concatenate([obs.displacements, U], 1))
    return LoadedModel(whole.experiment, o2, cup.mesh, cup.bottom_outer_facets, whole.force, h=whole.h,
                       linear_solver=whole.linear_solver)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--variants", nargs="+", default=["clean"])
    p.add_argument("--scales", type=float, nargs="+", default=[1.0])
    p.add_argument("--h", type=float, default=1.2, help="the global model's element size (mm)")
    p.add_argument("--h-data", type=float, default=1.2)
    p.add_argument("--spacing", type=float, default=0.6)
    p.add_argument("--noise", type=float, default=0.005)
    p.add_argument("--forces", type=float, nargs="+", default=[1.0, 2.0, 3.0, 4.0])
    p.add_argument("--clamp-all", action="store_true")
    p.add_argument("--layers", type=int, default=None, help="the model's elements through the bottom (default: "
                   "bottom / h rounded)")
    p.add_argument("--modulus", type=float, default=None, help="also the misfit at this uniform modulus held "
                   "(e.g. the sound cup holder's fitted one: benchmarks/_cup_null.py)")
    p.add_argument("--out", type=Path, default=HERE / "results" / "cup_bias.jsonl")
    args = p.parse_args()
    cache = Path(tempfile.gettempdir()) / "cup_bias_cache"
    cache.mkdir(exist_ok=True)
    g, hole, X, roles, U = data(args.seed, args.h_data, args.spacing, args.forces, cache)
    for variant in args.variants:
        Un = noisy(U, roles, X, g, variant, args.noise, args.seed)
        with tempfile.TemporaryDirectory() as tmp:
            whole, guide, validate = whole_model(g, X, roles, Un, args.forces, args.h, args.noise, Path(tmp),
                                                 args.layers)
            for scale in args.scales:
                row = {"seed": args.seed, "variant": variant, "h": args.h, "clamp_all": args.clamp_all,
                       "h_data": args.h_data, "layers": args.layers,
                       **evaluate(whole, hole, scale, guide, validate, args.noise, args.clamp_all, args.modulus),
                       "held_modulus": args.modulus,
                       "load": loadavg()}
                print(json.dumps(row), flush=True)
                with args.out.open("a") as fh:
                    fh.write(json.dumps(row) + "\n")


if __name__ == "__main__":
    main()
