"""``nonrigid diagnose BUNDLE --out DIR``: find what the initial model gets wrong, and the gain."""

from __future__ import annotations

import argparse
from pathlib import Path


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``diagnose`` sub-command to ``subparsers`` (from ``ArgumentParser.add_subparsers``)."""
    p = subparsers.add_parser("diagnose", help="find what the initial model gets wrong and measure the gain")
    p.add_argument("bundle")
    p.add_argument("--out", required=True, help="output directory (report.json and figures)")
    p.set_defaults(run=run)
    return p


def run(args: argparse.Namespace) -> int:
    """Carry out ``nonrigid diagnose`` (``args`` from the parser of :func:`add_parser`); 0 on success."""
    diagnose(args.bundle, args.out)
    return 0


def diagnose(bundle, out: str | Path, config=None, quiet: bool = False):
    """Diagnose a bundle (:func:`refine.diagnosis.diagnose`) and write its report.

    Args:
        bundle: a bundle directory (str or Path) or a :class:`refine.bundle.Bundle`.
        out: output directory (created if missing): ``report.json``, ``summary.txt`` and the
            figures of :func:`refine.diagnosis.report.write`, and ``refined/``, a bundle whose
            initial model is the chosen one (:func:`refine.diagnosis.refined.write`).
        config: a :class:`refine.diagnosis.DiagnoseConfig`; None: the defaults.
        quiet: print neither the progress log nor the summary.

    Returns:
        The :class:`refine.diagnosis.Diagnosis`.

    Raises:
        refine.exceptions.BundleError: the bundle directory is malformed.
    """
    from refine.bundle.io import read_bundle
    from refine.diagnosis import diagnose as diagnosis_of, refined, report

    if isinstance(bundle, (str, Path)):
        bundle = read_bundle(bundle)
    d = diagnosis_of(bundle, config, log=(lambda m: None) if quiet else print)
    path = report.write(d, out)
    again = refined.write(d, out)  # OUT/refined/: a bundle whose initial model is the chosen one
    if not quiet:
        print(report.summary(d))
        print(f"wrote {path} and figures in {Path(out)}" + (f"; the refined model as a bundle in {again}" if again else ""))
    return d
