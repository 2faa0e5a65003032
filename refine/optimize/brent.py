"""Brent's method in one dimension, as the paper uses it (Sec. 2.1, eq. 2; Numerical Recipes' brent).

Use it to recover one unknown property (a region's modulus, a hole's size) when each evaluation
of the error is a full finite-element solve and no derivative is available.

The search keeps a bracket [a, c] and the three best points seen so far (x, w, v). Each iteration
tries the vertex of the parabola through them, eq. (2). The parabolic step is accepted only if it
lands inside the bracket and moves less than half the step of the iteration before last (which
guarantees convergence); otherwise a golden-section step goes into the larger part of the bracket.
The first steps are golden (there are not yet three distinct points), later ones mostly parabolic,
as in the paper's Table 3.

Tolerance. As in Numerical Recipes (the paper's ref. [23]) ``tol`` is *relative to the parameter*:
with tol1 = tol |x| + abs_tol, no two evaluations are closer than tol1 ("the distance from a point
already evaluated to a new point is proportionally limited by the tolerance"), and the search stops
when the bracket around the best point x lies within x +- 2 tol1. So tol = 0.01 (the paper's
choice) locates a modulus of ~840 kPa within about +-17 kPa by the bracket; the parabolic steps make
the actual error usually much smaller (the paper reports ~0.1 %). Do not go below ~3e-8 (the square
root of float64 epsilon): a minimum is flat to that relative precision.
"""

from __future__ import annotations

import math
import time
from typing import Callable, NamedTuple, Sequence

from refine.exceptions import SearchError
from refine.optimize.result import RefineResult
from refine.optimize._evaluations import Evaluations

GOLDEN = 0.3819660112501051
"""(3 - sqrt 5) / 2: the fraction of the larger segment a golden-section step goes into."""


class BrentOutcome(NamedTuple):
    """Result of the core iteration: best point, its error, step log, stopping state."""

    x: float
    error: float
    rows: list[dict]
    converged: bool
    iterations: int


def parabola_vertex(a: float, b: float, c: float, fa: float, fb: float, fc: float) -> float:
    """The paper's eq. (2): abscissa of the vertex of the parabola through (a, fa), (b, fb), (c, fc).

    x = b - 1/2 [(b-a)^2 (fb-fc) - (b-c)^2 (fb-fa)] / [(b-a)(fb-fc) - (b-c)(fb-fa)].
    Returns nan when the three points are collinear (no vertex).
    """
    p, q = _parabolic_step(b, a, c, fb, fa, fc)
    return b + p / q if q != 0 else math.nan


def brent_search(
    f: Callable[[float], float],
    bracket: Sequence[float],
    *,
    tol: float = 0.01,
    abs_tol: float = 1e-10,
    max_iter: int = 100,
    name: str = "x",
    progress: bool = False,
) -> RefineResult:
    """Minimise a scalar function in a bracket with Brent's method (parabolic + golden section).

    Args:
        f: the error as a function of the parameter, f(x) -> float; each call is one forward solve.
        bracket: ``(a, b, c)``: the search interval [a, c] (expected range of the property) and the
            starting point b inside it, chosen by the user; f(a) and f(c) are never evaluated.
            ``(a, c)`` starts at the golden point a + 0.382 (c - a).
        tol: relative tolerance on the parameter (see the module docstring); the paper uses 0.01.
        abs_tol: absolute floor of the tolerance, parameter unit (matters only near x = 0).
        max_iter: iteration cap (each iteration is one evaluation).
        name: the parameter's name in ``values`` and in the history, e.g. ``"E_region"``.
        progress: show a tqdm bar of forward solves.

    Returns:
        RefineResult with ``values[name]`` the minimiser, ``error`` its f, ``n_forward`` the number
        of calls of f, and one history row per evaluation (``iteration``, name, ``error``, ``step``
        in {"initial", "golden", "parabolic"}, and the bracket ``lower``, ``upper`` after the step).
    """
    a, b, c = as_bracket(bracket)
    start = time.perf_counter()
    evals = Evaluations(f, progress, desc=f"brent {name}")
    out = brent_core(evals, a, b, c, tol=tol, abs_tol=abs_tol, max_iter=max_iter)
    note = evals.close()
    return RefineResult(
        values={name: out.x},
        error=out.error,
        n_forward=evals.n,
        seconds=time.perf_counter() - start,
        history=number_rows(out.rows, name),
        method="brent",
        converged=out.converged,
        message=_message(out, tol, max_iter) + note,
    )


def brent_core(
    f: Callable[[float], float], a: float, b: float, c: float, *, tol: float, abs_tol: float, max_iter: int
) -> BrentOutcome:
    """The iteration itself (Numerical Recipes' ``brent``), shared by the composite searches.

    ``a <= b <= c``; rows carry the parameter under the key ``"x"``.
    """
    if not tol > 0 or not abs_tol > 0 or max_iter < 1:
        raise SearchError(f"need tol > 0, abs_tol > 0 and max_iter >= 1, got {tol}, {abs_tol}, {max_iter}")
    lo, hi = a, c
    x = w = v = b
    fx = fw = fv = f(x)
    rows = [dict(x=x, error=fx, step="initial", lower=lo, upper=hi)]
    d = e = 0.0  # this step and the one before last
    for iteration in range(1, max_iter + 1):
        mid = 0.5 * (lo + hi)
        tol1 = tol * abs(x) + abs_tol
        if abs(x - mid) <= 2.0 * tol1 - 0.5 * (hi - lo):
            return BrentOutcome(x, fx, rows, True, iteration - 1)
        kind = "golden"
        if abs(e) > tol1 and math.isfinite(fx + fw + fv):
            p, q = _parabolic_step(x, w, v, fx, fw, fv)
            if q < 0.0:
                p, q = -p, -q
            e_before_last, e = e, d
            # Accept the parabola only inside the bracket and moving less than half the step before last.
            if abs(p) < abs(0.5 * q * e_before_last) and q * (lo - x) < p < q * (hi - x):
                kind, d = "parabolic", p / q
                if (x + d) - lo < 2.0 * tol1 or hi - (x + d) < 2.0 * tol1:
                    d = math.copysign(tol1, mid - x)
        if kind == "golden":
            e = (lo - x) if x >= mid else (hi - x)
            d = GOLDEN * e
        u = x + d if abs(d) >= tol1 else x + math.copysign(tol1, d)
        fu = f(u)
        if fu <= fx:
            if u >= x:
                lo = x
            else:
                hi = x
            v, w, x = w, x, u
            fv, fw, fx = fw, fx, fu
        else:
            if u < x:
                lo = u
            else:
                hi = u
            if fu <= fw or w == x:
                v, w, fv, fw = w, u, fw, fu
            elif fu <= fv or v == x or v == w:
                v, fv = u, fu
        rows.append(dict(x=u, error=fu, step=kind, lower=lo, upper=hi))
    return BrentOutcome(x, fx, rows, False, max_iter)


def number_rows(rows: list[dict], name: str) -> list[dict]:
    """History rows numbered from 1, the parameter key ``"x"`` renamed to ``name``."""
    return [{"iteration": i, **{(name if k == "x" else k): val for k, val in row.items()}}
            for i, row in enumerate(rows, start=1)]


def _parabolic_step(x, w, v, fx, fw, fv) -> tuple[float, float]:
    """Eq. (2) as a fraction p / q: the step from x to the vertex of the parabola through v, w, x.

    Kept as a fraction so that Brent can test acceptance without dividing by a tiny q.
    """
    r = (x - w) * (fx - fv)
    q = (x - v) * (fx - fw)
    p = (x - v) * q - (x - w) * r
    return -p, 2.0 * (q - r)


def as_bracket(bracket: Sequence[float]) -> tuple[float, float, float]:
    """Check and order a bracket ``(a, b, c)`` or ``(a, c)``; returns ``(a, b, c)`` with a <= b <= c."""
    values = [float(t) for t in bracket]
    if len(values) == 2:
        a, c = sorted(values)
        values = [a, a + GOLDEN * (c - a), c]
    if len(values) != 3 or not all(math.isfinite(t) for t in values):
        raise SearchError(f"bracket must be (a, b, c) or (a, c) of finite numbers, got {bracket!r}")
    a, b, c = values
    a, c = min(a, c), max(a, c)
    if not (a <= b <= c) or a == c:
        raise SearchError(f"the middle point b = {b} must lie in the bracket [{a}, {c}] of non-zero width")
    return a, b, c


def _message(out: BrentOutcome, tol: float, max_iter: int) -> str:
    if out.converged:
        return f"bracket shrunk to the relative tolerance {tol:g} in {out.iterations} iterations."
    return f"stopped after max_iter = {max_iter} iterations before reaching the tolerance {tol:g}."
