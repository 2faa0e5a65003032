"""A hidden inclusion's fitted volume against the model mesh's size.

What a hidden inclusion's small fitted volume is: the model mesh, or the surface data's own
ambiguity (issue 23; benchmarks/inclusion3d.py fits came out 40-60 % small).

For one seed it draws the block of benchmarks/inclusion3d.py (data tet10 at --h-data with noise,
surface points only) and, per model mesh size in --h-models:

- chi2 of the guide points at the truth's ellipsoid as the model represents it;
- the inclusion fitted from the truth (10 unknowns, LM): its volume, ratio, strength, chi2;
- the profile's point at the truth's ratio (the nine shape unknowns refitted,
  refine.solid.inclusion_profile.RatioHeld): its chi2 rise over the fit's and its volume.

A rise within the threshold (4 x the fit's reduced chi2) puts the truth's ratio inside the
profile interval the report gives; the volume refitted there says whether the surface fixes the
volume at a given ratio. It writes benchmarks/results/inclusion3d_mesh.json (rows, targets) and
inclusion3d_mesh.png.

    python -m benchmarks inclusion3d_mesh --seed 11 --h-models 4 3
    python -m benchmarks inclusion3d_mesh --seed 13 --cause softer-region --h-data 2 --h-models --graded 2.5 5

``--graded FINE COARSE`` adds a box graded from FINE mm around the truth's extent to COARSE mm
(refine.solid.inclusion_mesh.focused_mesh, as the diagnosis grades around its coarse fit).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from types import SimpleNamespace

HERE = Path(__file__).resolve().parent

import numpy as np  # noqa: E402

from benchmarks._timing import loadavg  # noqa: E402
from benchmarks._cli import QUICK, quick  # noqa: E402

RESULTS = HERE / "results"


def row(bundle, truth, setting, h: float, fine: float | None = None) -> dict:
    """One model mesh's figures (see the module): a box at ``h`` (mm), or with ``fine`` a box graded
    from ``fine`` around the truth's extent to ``h`` (refine.solid.inclusion_mesh)."""
    from dataclasses import replace

    from refine.diagnosis.fitted import fit
    from refine.measures import Residuals
    from refine.model.measured import MeasuredModel
    from refine.model.objective import Compiled
    from refine.optimize.levenberg_marquardt import levenberg_marquardt
    from refine.solid.inclusion import Inclusion
    from refine.solid.inclusion_diagnosis import with_errors
    from refine.solid.inclusion_profile import RatioHeld, strength
    from refine.solid.inclusion_mesh import FocusedMesh, focused_mesh
    from examples.block.synthetic import model_mesh

    t0 = time.perf_counter()
    obs, sigma = bundle.observations, setting.noise
    guide, validate = obs.roles == "guide", obs.roles == "validate"
    mesh = model_mesh(replace(setting, h_model=h))
    if fine is not None:
        mesh = focused_mesh(mesh, [SimpleNamespace(centroid=truth.centre, axes=truth.axes, rotation=truth.rotation)],
                            FocusedMesh(fine=fine, coarse=h))
    model = MeasuredModel(bundle.experiment, obs, mesh=mesh)
    at = Residuals.at(obs.displacements, guide, sigma)
    hyp = Inclusion(model, truth.centre, truth.axes, truth.rotation, truth.ratio)
    compiled, z0 = hyp.build()
    chi2_truth = at.chi2(compiled.predict(z0))
    f = with_errors(fit(hyp, guide, validate, sigma), guide, sigma)
    s = f.shapes[0]
    threshold = 4.0 * max(f.chi2_fit / max(at.n - f.z.size, 1), 1.0)
    held = RatioHeld(f.compiled.param, float(np.log(truth.ratio)), np.asarray(f.z)[1:])
    c = Compiled(model, held, f.compiled.theta)
    res = levenberg_marquardt(c, guide, sigma, z0=held.start, max_steps=12, chi2_tol=0.1)
    zs = np.asarray(res.values["z"])
    rise = at.chi2(c.predict(zs)) - f.chi2_fit
    out = {"h_model": h, "fine": fine, "cells": int(mesh.n_cells), "chi2_truth_shape": chi2_truth, "chi2_fit": f.chi2_fit,
           "n_residuals": int(at.n), "fit": {"volume": s.volume, "ratio": s.ratio,
                                             "strength": float(strength(s.volume, s.ratio, setting.nu))},
           "volume_error_pct": 100 * (s.volume / truth.volume - 1), "ratio_error_pct": 100 * (s.ratio / truth.ratio - 1),
           "rise_at_truth_ratio": rise, "threshold": threshold, "truth_ratio_inside": bool(rise <= threshold),
           "volume_at_truth_ratio": held.shape(zs).volume, "seconds": time.perf_counter() - t0, "load": loadavg()}
    print(json.dumps(out), flush=True)
    return out


def main(argv=None) -> int:
    argv = quick(argv, ["--h-models", "4", "--out", str(QUICK / "inclusion3d_mesh.json")])
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seed", type=int, default=11)
    p.add_argument("--cause", default="stiffer-region")
    p.add_argument("--h-data", type=float, default=2.5)
    p.add_argument("--h-models", type=float, nargs="*", default=[4.0, 3.0])
    p.add_argument("--graded", type=float, nargs=2, action="append", default=[], metavar=("FINE", "COARSE"),
                   help="a box graded from FINE mm around the truth to COARSE mm (repeatable)")
    p.add_argument("--out", type=Path, default=RESULTS / "inclusion3d_mesh.json")
    args = p.parse_args(argv)
    from refine.solid.inclusion_profile import strength
    from examples.block.synthetic import BlockSetting, block_bundle

    setting = BlockSetting(h_data=args.h_data, h_model=max([*args.h_models, *(g[1] for g in args.graded)]))
    bundle, _, truth = block_bundle(args.cause, args.seed, setting)
    rows = [row(bundle, truth, setting, h) for h in args.h_models]
    rows += [row(bundle, truth, setting, coarse, fine) for fine, coarse in args.graded]
    finest = min(rows, key=lambda r: r["fine"] or r["h_model"])
    targets = {"truth_ratio_inside_on_the_finest_model": {"value": finest["rise_at_truth_ratio"],
                                                          "pass": finest["truth_ratio_inside"]},
               "volume_at_truth_ratio_within_10pct": {"value": finest["volume_at_truth_ratio"], "pass": bool(
                   abs(finest["volume_at_truth_ratio"] / truth.volume - 1) <= 0.1)}}
    out = {"seed": args.seed, "cause": args.cause, "truth": {"volume": truth.volume, "ratio": truth.ratio,
                                                             "strength": float(strength(truth.volume, truth.ratio,
                                                                                        setting.nu))},
           "rows": rows, "targets": targets, "settings": {k: str(v) for k, v in vars(args).items()}}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(out, indent=1), encoding="utf-8")
    plot(out, args.out.with_suffix(".png"))
    print(json.dumps(targets, indent=1))
    return 0


def plot(out, path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 2, figsize=(9, 3.5))
    h = [f"{r['h_model']:g}" if r.get("fine") is None else f"{r['fine']:g}-{r['h_model']:g}" for r in out["rows"]]
    ax[0].plot(h, [r["volume_error_pct"] for r in out["rows"]], "o-", label="volume")
    ax[0].plot(h, [r["ratio_error_pct"] for r in out["rows"]], "s-", label="ratio")
    ax[0].axhline(0, color="k", lw=0.5)
    ax[0].set_xlabel("model element size (mm; graded: fine-coarse)")
    ax[0].set_ylabel("fit's error (%)")
    ax[0].legend()
    ax[1].bar(h, [r["rise_at_truth_ratio"] for r in out["rows"]])
    ax[1].axhline(out["rows"][-1]["threshold"], color="C1", ls="--", label="threshold")
    ax[1].set_xlabel("model element size (mm; graded: fine-coarse)")
    ax[1].set_ylabel("chi2 rise at the truth's ratio")
    ax[1].legend()
    fig.suptitle(f"seed {out['seed']} {out['cause']} (load {out['rows'][-1]['load']:.1f})")
    fig.tight_layout()
    fig.savefig(path, dpi=100)


if __name__ == "__main__":
    raise SystemExit(main())
