"""Bookkeeping shared by the derivative-free searches: counted, remembered objective evaluations."""

from __future__ import annotations

import math
from typing import Callable

import numpy as np


class Evaluations:
    """Wraps an objective so that every real call is counted as one forward solve.

    A repeated call at exactly the same parameters is answered from memory and not counted
    (coordinate-wise Brent restarts each 1-D search at the point it already knows). A non-finite
    objective value (a failed forward solve) is turned into +inf, so the searches move away from it.

    Attributes:
        n: number of real calls made so far.
        non_finite: number of those that returned NaN or inf.
    """

    def __init__(self, f: Callable, progress: bool = False, desc: str = "search"):
        self._f = f
        self._memory: dict[tuple[float, ...], float] = {}
        self.n = 0
        self.non_finite = 0
        self._bar = None
        if progress:
            from tqdm.auto import tqdm

            self._bar = tqdm(desc=desc, unit="solve")

    def __call__(self, x) -> float:
        key = tuple(np.atleast_1d(np.asarray(x, dtype=np.float64)).tolist())
        if key in self._memory:
            return self._memory[key]
        value = float(self._f(x))
        self.n += 1
        if not math.isfinite(value):
            self.non_finite += 1
            value = math.inf
        self._memory[key] = value
        if self._bar is not None:
            self._bar.update(1)
            self._bar.set_postfix(x=np.round(key, 6).tolist() if len(key) > 1 else key[0], error=value)
        return value

    def close(self) -> str:
        """Close the progress bar; returns a note on failed evaluations for the result message."""
        if self._bar is not None:
            self._bar.close()
        if self.non_finite:
            return f" {self.non_finite} evaluation(s) returned NaN/inf and were treated as +inf."
        return ""
