"""``nonrigid demo [--out DIR]``: a synthetic sheet with a hidden inclusion, end to end."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``demo`` sub-command to ``subparsers`` (from ``ArgumentParser.add_subparsers``)."""
    p = subparsers.add_parser("demo", help="generate a sheet with a hidden inclusion and analyse it")
    p.add_argument("--out", default="nonrigid-demo", help="output directory (default: ./nonrigid-demo)")
    p.add_argument("--seed", type=int, default=None, help="random seed of the hidden inclusion")
    p.set_defaults(run=run)
    return p


def run(args: argparse.Namespace) -> int:
    """Carry out ``nonrigid demo`` (``args`` from the parser of :func:`add_parser`); 0 on success."""
    demo(args.out, args.seed)
    return 0


def demo(out: str | Path = "nonrigid-demo", seed: int | None = None):
    """Hide a stiffer disc in a synthetic 100 x 60 mm sheet, then simulate and diagnose it, printing
    what was found next to the truth.

    Args:
        out: output directory: ``bundle/`` (the synthetic bundle), ``simulate/`` (see
            :func:`refine.cli.simulate`) and ``diagnose/`` (report and figures).
        seed: random seed of the hidden disc and of the noise; None: a fresh one, printed.

    Returns:
        The :class:`refine.diagnosis.Diagnosis` of the bundle.
    """
    from refine.bundle.io import write_bundle
    from refine.cli.diagnose import diagnose
    from refine.cli.simulate import simulate
    from refine.diagnosis import report
    from refine.demo_data import random_truth, synthetic_bundle

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
    summary = simulate(str(out_dir / "bundle"), str(out_dir / "simulate"), quiet=True)
    print(f"the uniform initial model misses the validation points by {summary['validate_error']:.3f} mm on average; "
          "diagnosing ...")
    d = diagnose(str(out_dir / "bundle"), str(out_dir / "diagnose"), quiet=True)
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
    return d
