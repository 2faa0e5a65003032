"""``nonrigid batch diagnose``: diagnose many bundles on a Dask cluster.

    nonrigid batch diagnose runs/*/bundle --out reports                # this machine, one worker per core
    nonrigid batch diagnose --list bundles.txt --out reports --workers 4 --threads-per-worker 2
    nonrigid batch diagnose 'runs/*/bundle' --out reports --scheduler tcp://head:8786   # a cluster

Each bundle's report goes to DIR/<bundle name>/ and its row (cause, centroid, ratio, gain, seconds,
worker, error) to DIR/results.jsonl as soon as it finishes; running the same command again skips
the bundles already done. A bundle that fails is recorded with its error and the batch goes on. At
the end DIR/summary.txt and DIR/batch.png. Needs ``pip install nonrigid[batch]``.

Exit status: 0 when every bundle was diagnosed, 1 when some failed (see DIR/results.jsonl and
DIR/<name>/error.txt), 2 when the batch could not start.
"""

from __future__ import annotations

import argparse
import sys

from refine.exceptions import RefineError


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``batch`` command (with its ``diagnose`` sub-command) to ``subparsers`` (from
    ``ArgumentParser.add_subparsers``)."""
    p = subparsers.add_parser("batch", help="diagnose many bundles on a Dask cluster",
                              description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="batch_command", required=True)
    d = sub.add_parser("diagnose", help="diagnose many bundles, one report each and a results table",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    d.add_argument("bundles", nargs="*", metavar="BUNDLES",
                   help="bundle directories or glob patterns (quoted patterns are expanded by nonrigid)")
    d.add_argument("--list", metavar="FILE", help="text file of bundle paths or patterns, one a line")
    d.add_argument("--out", required=True, metavar="DIR", help="output directory: reports and results.jsonl")
    d.add_argument("--scheduler", metavar="ADDRESS",
                   help="address of a running Dask scheduler (tcp://host:8786); default: a local cluster")
    d.add_argument("--workers", type=int, metavar="N",
                   help="local worker processes (default: one per GPU, else one per core / threads)")
    d.add_argument("--threads-per-worker", type=int, metavar="N", help="cores of each local worker (default 1)")
    d.add_argument("--no-figures", action="store_true", help="write report.json and summary.txt only")
    d.add_argument("--retry-failed", action="store_true", help="run the bundles that failed before again")
    d.add_argument("--quiet", action="store_true", help="no progress bar and no summary table")
    p.set_defaults(run=run)
    return p


def run(args: argparse.Namespace) -> int:
    """Carry out ``nonrigid batch diagnose`` (``args`` from the parser of :func:`add_parser`); the
    exit status of the module docstring."""
    try:
        from refine.batch import bundle_paths, diagnose_many

        if args.scheduler is not None and (args.workers is not None or args.threads_per_worker is not None):
            print("nonrigid batch: note: --workers and --threads-per-worker are those of the cluster at "
                  f"{args.scheduler}; ignored", file=sys.stderr)
        paths = bundle_paths(args.bundles, args.list)
        table = diagnose_many(paths, args.out, scheduler=args.scheduler, workers=args.workers,
                              threads_per_worker=args.threads_per_worker, progress=not args.quiet,
                              figures=not args.no_figures, retry_failed=args.retry_failed)
    except (RefineError, OSError) as e:
        print(f"nonrigid batch {args.batch_command}: error: {e}", file=sys.stderr)
        return 2
    if not args.quiet:
        print(table.summary())
        print(f"wrote {args.out}/results.jsonl, summary.txt, batch.png and one report folder per bundle")
    return 1 if table.failed else 0
