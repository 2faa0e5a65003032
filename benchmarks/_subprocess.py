"""A benchmark module run again in a fresh interpreter (each case in its own process, so that
compiled programs do not pile up): :func:`command` and :func:`environment`."""

from __future__ import annotations

import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def command(module: str, *args) -> list[str]:
    """``python -m benchmarks.MODULE ARGS...`` for :func:`subprocess.run` (with :func:`environment`)."""
    return [sys.executable, "-m", f"benchmarks.{module}", *map(str, args)]


def environment(first: tuple[str, ...] = (), **extra: str) -> dict[str, str]:
    """``os.environ`` with ``first`` then the repository root in front of ``PYTHONPATH`` (so that
    ``benchmarks`` imports from any working directory; ``first`` holds a tree whose ``refine``
    should win), and ``extra`` set."""
    path = os.pathsep.join(filter(None, [*first, str(ROOT), os.environ.get("PYTHONPATH")]))
    return {**os.environ, **extra, "PYTHONPATH": path}
