"""The ``nonrigid`` command line.

    nonrigid simulate BUNDLE --out DIR    drive the bundle's initial model with its boundary points
    nonrigid diagnose BUNDLE --out DIR    find what the initial model gets wrong, and the gain
    nonrigid track --pattern grid|speckle --scale MM_PER_PX --roi X0,Y0,X1,Y1 IMAGES... --out BUNDLE
    nonrigid demo [--out DIR]             a synthetic sheet with a hidden inclusion, end to end
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np


def _simulate(bundle_path: str, out: str, h: float | None = None, quiet: bool = False) -> dict:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    import jaxfem as jf

    from refine.bundle.io import read_bundle, write_displacements_csv
    from refine.measures import mean_position_error, tracking_error
    from refine.model.measured import MeasuredModel

    t0 = time.perf_counter()
    bundle = read_bundle(bundle_path)
    model = MeasuredModel(bundle.experiment, bundle.observations, h=h, root=bundle.root)
    theta = model.params()
    obs = bundle.observations
    out_dir = Path(out)
    out_dir.mkdir(parents=True, exist_ok=True)
    U, start, preds = [], None, []
    for f in range(obs.n_frames):
        th = {**theta, "u_D": model.prescribed(f)}
        sol = model.solver.solve(th, start=start)  # raises SolverError naming the load step
        start = (sol.u.reshape(-1), {"u_D": th["u_D"], "f": th["f"], "traction": th["traction"]})
        U.append(sol)
        preds.append(np.asarray(model.probe(sol.u)))
        ax = jf.plot.strain_map(model.solver, sol.u, th, points=obs.reference + np.nan_to_num(obs.displacements[f]),
                                title=f"{bundle.experiment.name}: frame {f + 1}, initial model")
        ax.figure.savefig(out_dir / f"strain_frame{f + 1:02d}.png", dpi=120, bbox_inches="tight")
        plt.close(ax.figure)
    pred = np.stack(preds)
    write_displacements_csv(out_dir / "displacements.csv", obs.ids, pred)
    summary = {"frames": obs.n_frames, "points": obs.n_points, "cells": model.mesh.n_cells,
               "newton_iterations": int(sum(int(s.info["iterations"]) for s in U)),
               "seconds": time.perf_counter() - t0}
    for role in ("guide", "validate"):
        m = obs.mask(role)
        if m.any():
            summary[f"{role}_error"] = mean_position_error(pred[:, m], obs.displacements[:, m]).value
    if obs.mask("validate").any():
        m = obs.mask("validate")
        summary["tracking_error"] = tracking_error(pred[:, m], obs.displacements[:, m]).value
    if not quiet:
        print(f"simulated {summary['frames']} frames of {bundle.experiment.name!r} on {summary['cells']} cells "
              f"({summary['newton_iterations']} Newton iterations, {summary['seconds']:.1f} s)")
        for k in ("guide_error", "validate_error", "tracking_error"):
            if k in summary:
                print(f"  {k.replace('_', ' ')}: {summary[k]:.4g}")
        print(f"  wrote {out_dir / 'displacements.csv'} and {obs.n_frames} strain maps")
    return summary


def _diagnose(bundle_path: str, out: str, quiet: bool = False):
    from refine.diagnosis import report
    from refine.bundle.io import read_bundle
    from refine.diagnosis import diagnose

    bundle = read_bundle(bundle_path)
    d = diagnose(bundle, log=(lambda m: None) if quiet else print)
    path = report.write(d, out)
    if not quiet:
        print(report.summary(d))
        print(f"wrote {path} and figures in {Path(out)}")
    return d


def _demo(out: str, seed: int | None) -> None:
    from refine.bundle.io import write_bundle
    from refine.synthetic.sheet import random_truth, synthetic_bundle

    seed = int(np.random.SeedSequence().entropy % 10_000) if seed is None else seed
    rng = np.random.default_rng(seed)
    truth = random_truth(rng, "stiffer-region")
    inc = truth.inclusions[0]
    print(f"demo (seed {seed}): a 100 x 60 mm sheet region tracked on a 5 mm grid, pulled 15 %,")
    print(f"  hiding a stiffer disc at ({inc.shape.cx:.1f}, {inc.shape.cy:.1f}) mm, radius {inc.shape.rx:.1f} mm, "
          f"{inc.ratio:.1f}x stiffer (data from a finer quadratic mesh, noise 0.02 mm)")
    bundle = synthetic_bundle(truth, seed=seed, name=f"demo-{seed}")
    out_dir = Path(out)
    write_bundle(out_dir / "bundle", bundle)
    print(f"  wrote the bundle to {out_dir / 'bundle'}")
    summary = _simulate(str(out_dir / "bundle"), str(out_dir / "simulate"), quiet=True)
    print(f"the uniform initial model misses the validation points by {summary['validate_error']:.3f} mm on average; "
          "diagnosing ...")
    d = _diagnose(str(out_dir / "bundle"), str(out_dir / "diagnose"), quiet=True)
    from refine.diagnosis import report

    print(report.summary(d))
    print("truth:   stiffer-region centred at "
          f"({inc.shape.cx:.1f}, {inc.shape.cy:.1f}), area {np.pi * inc.shape.rx * inc.shape.ry:.1f}, "
          f"{inc.ratio:.2f}x the background")
    found = [f for f in d.findings if f["cause"] == "stiffer-region"]
    if found:
        c = found[0]["region"]["centroid"]
        err = np.hypot(c[0] - inc.shape.cx, c[1] - inc.shape.cy)
        print(f"centroid off by {err:.2f} mm ({100 * err / np.hypot(100, 60):.1f} % of the diagonal), "
              f"ratio off by {100 * abs(found[0]['relative_elasticity'] / inc.ratio - 1):.1f} %")
    print(f"report and figures: {out_dir / 'diagnose'}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="nonrigid", description="Nonrigid motion analysis with "
                                     "differentiable finite elements.")
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("simulate", help="drive the bundle's initial model with its boundary points")
    p.add_argument("bundle")
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--h", type=float, default=None, help="element size (default: half the point spacing)")
    p = sub.add_parser("diagnose", help="find what the initial model gets wrong and measure the gain")
    p.add_argument("bundle")
    p.add_argument("--out", required=True, help="output directory (report.json and figures)")
    from refine.cli import track as track_cmd

    track_cmd.add_parser(sub)
    p = sub.add_parser("demo", help="generate a sheet with a hidden inclusion and analyse it")
    p.add_argument("--out", default="nonrigid-demo", help="output directory (default: ./nonrigid-demo)")
    p.add_argument("--seed", type=int, default=None, help="random seed of the hidden inclusion")
    args = parser.parse_args(argv)
    from jaxfem.exceptions import JaxfemError
    from refine.exceptions import RefineError

    try:
        if args.command == "track":
            return track_cmd.run(args)
        if args.command == "simulate":
            _simulate(args.bundle, args.out, args.h)
        elif args.command == "diagnose":
            _diagnose(args.bundle, args.out)
        elif args.command == "demo":
            _demo(args.out, args.seed)
    except (JaxfemError, RefineError, FileNotFoundError) as e:
        print(f"nonrigid {args.command}: error: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
