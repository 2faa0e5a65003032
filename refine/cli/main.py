"""The ``nonrigid`` command line.

    nonrigid simulate BUNDLE --out DIR    drive the bundle's initial model with its boundary points
    nonrigid diagnose BUNDLE --out DIR    find what the initial model gets wrong, and the gain
    nonrigid track --pattern grid|speckle --scale MM_PER_PX --roi X0,Y0,X1,Y1 IMAGES... --out BUNDLE
    nonrigid import --format dice|csv --scale MM_PER_UNIT EXPORT... --out BUNDLE
    nonrigid batch diagnose BUNDLES... --out DIR   many bundles on a Dask cluster (extra: nonrigid[batch])
    nonrigid demo [--out DIR]             a synthetic sheet with a hidden inclusion, end to end
    nonrigid follow BUNDLE --out DIR      follow unlabelled clouds (clouds.csv), refining where prediction fails

Each command is a module of :mod:`refine.cli` with ``add_parser(subparsers)``, ``run(args)`` and a
public function that does the work; a new command is a new module named in :data:`COMMANDS`.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from importlib.metadata import PackageNotFoundError, version

COMMANDS = ("simulate", "diagnose", "track", "import_export", "batch", "demo", "follow", "mesh", "cache")  # modules of refine.cli, in the order of --help


def build_parser() -> argparse.ArgumentParser:
    """The parser of ``nonrigid`` with every command of :data:`COMMANDS`; each sets ``args.run``."""
    parser = argparse.ArgumentParser(prog="nonrigid", description="Nonrigid motion analysis with "
                                     "differentiable finite elements.")
    parser.add_argument("--version", action="version", version=f"%(prog)s {_installed_version()}")
    parser.add_argument("--debug", action="store_true", help="show the traceback of an unexpected error")
    sub = parser.add_subparsers(dest="command", required=True)
    for name in COMMANDS:
        # import_module, not attribute access: refine.cli exports the command functions under these names
        importlib.import_module(f"refine.cli.{name}").add_parser(sub)
    return parser


def main(argv=None) -> int:
    """Run ``nonrigid`` with ``argv`` (default: ``sys.argv[1:]``); the exit status.

    An error of the input (a RefineError, TrackingError, JaxfemError, OSError or ValueError) is one
    line on stderr, ``nonrigid CMD: error: ...``, and exit status 2; any other exception is one line
    too, with a hint to rerun with ``--debug`` (which lets it propagate with its traceback), and
    exit status 1.
    """
    args = build_parser().parse_args(argv)
    from jaxfem.exceptions import JaxfemError
    from refine.exceptions import RefineError
    from tracking import TrackingError

    try:
        return args.run(args)
    except (JaxfemError, RefineError, TrackingError, OSError, ValueError) as e:
        if args.debug:
            raise
        print(f"nonrigid {args.command}: error: {_one_line(e)}", file=sys.stderr)
        return 2
    except Exception as e:  # noqa: BLE001 - an internal error: one line, the traceback under --debug
        if args.debug:
            raise
        print(f"nonrigid {args.command}: internal error: {type(e).__name__}: {_one_line(e)}; rerun with "
              "--debug for the traceback", file=sys.stderr)
        return 1


def _one_line(error: BaseException) -> str:
    """The message of ``error`` on one line (its lines joined by '; '), or its type's name if empty."""
    text = "; ".join(line.strip() for line in str(error).splitlines() if line.strip())
    return text or type(error).__name__


def _installed_version() -> str:
    try:
        return version("nonrigid")
    except PackageNotFoundError:  # run from a source tree that was never installed
        return "(not installed)"


if __name__ == "__main__":
    sys.exit(main())
