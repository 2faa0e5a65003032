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
    sub = parser.add_subparsers(dest="command", required=True)
    for name in COMMANDS:
        # import_module, not attribute access: refine.cli exports the command functions under these names
        importlib.import_module(f"refine.cli.{name}").add_parser(sub)
    return parser


def main(argv=None) -> int:
    """Run ``nonrigid`` with ``argv`` (default: ``sys.argv[1:]``); the exit status, 2 on an error
    of the input (its message on stderr)."""
    args = build_parser().parse_args(argv)
    from jaxfem.exceptions import JaxfemError
    from refine.exceptions import RefineError

    try:
        return args.run(args)
    except (JaxfemError, RefineError, FileNotFoundError) as e:
        print(f"nonrigid {args.command}: error: {e}", file=sys.stderr)
        return 2


def _installed_version() -> str:
    try:
        return version("nonrigid")
    except PackageNotFoundError:  # run from a source tree that was never installed
        return "(not installed)"


if __name__ == "__main__":
    sys.exit(main())
