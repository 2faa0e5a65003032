"""Timing helpers shared by forward.py and its peers: best-of-N wall seconds and the load average."""

from __future__ import annotations

import time


def best_of(fn, repeats=3, budget=None):
    """(best seconds, all seconds, last result) of ``repeats`` calls; stops early past ``budget`` seconds."""
    times, out, spent = [], None, 0.0
    for _ in range(repeats):
        t = time.perf_counter()
        out = fn()
        dt = time.perf_counter() - t
        times.append(dt)
        spent += dt
        if budget is not None and spent > budget:
            break
    return min(times), times, out


def loadavg() -> float:
    try:
        return float(open("/proc/loadavg").read().split()[0])
    except OSError:
        return float("nan")

