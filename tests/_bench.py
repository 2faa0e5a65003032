"""Benchmark scripts imported as modules by the tests that check them (benchmarks/ is not a
package): :func:`benchmark_modules`."""

from __future__ import annotations

import importlib
import sys
from contextlib import contextmanager
from pathlib import Path

BENCH = Path(__file__).resolve().parents[1] / "benchmarks"


@contextmanager
def benchmark_modules(*names: str):
    """The benchmark modules ``names`` (e.g. ``"scar"``, ``"_hand_threshold"``) as a tuple, with
    benchmarks/ on ``sys.path`` while they are used (as their own imports and spawned workers need);
    afterwards the path and the modules are taken away again, so a later test imports them afresh."""
    sys.path.insert(0, str(BENCH))
    try:
        yield tuple(importlib.import_module(name) for name in names)
    finally:
        sys.path.remove(str(BENCH))
        for name in names:
            sys.modules.pop(name, None)
