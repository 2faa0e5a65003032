"""``--quick`` for a benchmark whose own options already hold a small run: :func:`quick`."""

from __future__ import annotations

import sys
from pathlib import Path

QUICK = Path(__file__).resolve().parent / "results" / "quick"  # not committed (.gitignore)


def quick(argv, small: list[str]) -> list[str]:
    """``argv`` (``sys.argv[1:]`` when None) with ``--quick`` replaced by the options ``small``, put
    first so that options given beside ``--quick`` still win; ``QUICK`` is created for the smoke
    run's files."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if "--quick" not in argv:
        return argv
    QUICK.mkdir(parents=True, exist_ok=True)
    return [*small, *(a for a in argv if a != "--quick")]
