"""Coordinate-wise Brent: several parameters, one 1-D Brent search each, cycled until nothing moves.

A baseline for a few regions (two inclusions, a modulus and a size): simple and derivative-free
but slow when the parameters interact, since every sweep costs a full Brent search per parameter.
Prefer a gradient-based fit when the forward solver gives derivatives.
"""

from __future__ import annotations

import time
from typing import Callable, Sequence

import numpy as np

from refine.exceptions import SearchError
from refine.optimize.result import RefineResult
from refine.optimize._evaluations import Evaluations
from refine.optimize.brent import as_bracket, brent_core


def coordinate_brent_search(
    f: Callable[[np.ndarray], float],
    brackets: Sequence[Sequence[float]],
    *,
    names: Sequence[str] | None = None,
    tol: float = 0.01,
    abs_tol: float = 1e-10,
    max_sweeps: int = 20,
    max_iter: int = 100,
    progress: bool = False,
) -> RefineResult:
    """Minimise f(x), x of n parameters, by repeated sweeps of 1-D Brent searches.

    Sweep: for each parameter i in turn, Brent over [a_i, c_i] starting at the current x_i with
    the others held. Stops when in one sweep no parameter moved by more than Brent's own
    resolution 2 (tol |x_i| + abs_tol) (with one parameter, after the first sweep).

    Args:
        f: error of the parameter vector ``(n,)`` float; each new call is one forward solve
            (a call at a point already evaluated is answered from memory and not counted).
        brackets: n triples ``(a_i, b_i, c_i)``: bounds and starting value of each parameter.
        names: parameter names for ``values`` and the history (default ``x0, x1, ...``).
        tol: of each 1-D Brent search, relative on the parameter.
        abs_tol: of each 1-D Brent search.
        max_iter: of each 1-D Brent search.
        max_sweeps: cap on the number of sweeps.
        progress: show a tqdm bar of forward solves.

    Returns:
        RefineResult; history rows carry ``sweep``, the varied ``parameter``, all parameter values,
        ``error``, ``step`` and the bracket of the varied parameter.
    """
    triples = [as_bracket(t) for t in brackets]
    if not triples:
        raise SearchError("coordinate_brent_search needs at least one bracket")
    names = [f"x{i}" for i in range(len(triples))] if names is None else list(names)
    if len(names) != len(triples) or len(set(names)) != len(names):
        raise SearchError(f"need {len(triples)} distinct names, got {names}")
    start = time.perf_counter()
    evals = Evaluations(f, progress, desc="coordinate brent")
    x = np.array([b for _, b, _ in triples], dtype=np.float64)
    rows, converged, error, all_inner_converged = [], False, np.nan, True

    for sweep in range(1, max_sweeps + 1):
        moved = False
        for i, (a, _, c) in enumerate(triples):
            def along(t, i=i):
                trial = x.copy()
                trial[i] = t
                return evals(trial)

            out = brent_core(along, a, float(x[i]), c, tol=tol, abs_tol=abs_tol, max_iter=max_iter)
            all_inner_converged &= out.converged
            for row in out.rows:
                values = dict(zip(names, x.tolist()))
                values[names[i]] = row["x"]
                rows.append(dict(sweep=sweep, parameter=names[i], **values, error=row["error"], step=row["step"],
                                 lower=row["lower"], upper=row["upper"]))
            moved |= abs(out.x - x[i]) > 2.0 * (tol * abs(out.x) + abs_tol)
            x[i], error = out.x, out.error
        if not moved or len(triples) == 1:
            converged = True
            break

    note = evals.close()
    message = (f"no parameter moved beyond the tolerance {tol:g} in sweep {sweep}." if converged
               else f"still moving after max_sweeps = {max_sweeps} sweeps.")
    if not all_inner_converged:
        message += f" Some 1-D searches hit max_iter = {max_iter}."
    return RefineResult(
        values=dict(zip(names, x.tolist())),
        error=float(error),
        n_forward=evals.n,
        seconds=time.perf_counter() - start,
        history=[{"iteration": k, **row} for k, row in enumerate(rows, start=1)],
        method="coordinate-brent",
        converged=converged and all_inner_converged,
        message=message + note,
    )
