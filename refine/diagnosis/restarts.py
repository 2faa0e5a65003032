"""Restarts of a shape fit from where it put the shapes' centres: the misfit of a small region
seen by few tracked points has local minima, and a fit started off the centre settles in one.

While a fit moves a region's centre to where the data put it, the morph that carries the
outline along shears it, and the outline, the size and the ratio trade against each other
(a larger, weaker region moves the points much as a smaller, stronger one): the fit stops in
the first minimum of that trade it meets. The centre is what the data fix best, so each restart
keeps the fitted centres and ratios and starts the outline afresh (:data:`RESTARTS`); the fit
with the lowest misfit on the fitting points is kept. Restarts make a lower minimum likelier,
never certain (``benchmarks/error_coverage.py`` measures them). A hole's fit restarts the same
way where asked (:func:`~refine.diagnosis.holes.fit_hole`'s ``restarts``). A stiff region also
restarts along the size-ratio valley (:mod:`refine.diagnosis.valley`): a circle wider or
narrower by :data:`VALLEY_STEP` at the ratio of the same strength, the other side of the
valley's bend from a fit stopped on its small, stiff side.
"""

from __future__ import annotations

from dataclasses import fields, replace

import numpy as np

from refine.diagnosis.valley import ratio_along_valley

RESTARTS = ("recentred", "round", "larger", "smaller")
"""The restarts tried, in order: ``"recentred"``, the starting outline (axes and angle as
started) moved to the fitted centre; ``"round"``, a circle (a square for a rectangle) of the
fitted area at the fitted centre. Each keeps the fitted ratio (a hole has none). ``"larger"``
and ``"smaller"``: that circle :data:`VALLEY_STEP` times wider or narrower, at the ratio of the
same strength (:func:`~refine.diagnosis.valley.ratio_along_valley`): the other side of the bend
of the size-ratio valley (regions only; skipped where no ratio reaches that strength)."""

CHOSEN_RESTARTS = ("round", "larger", "smaller")
"""The restarts of the region a diagnosis chose (its search fits each hypothesis once)."""

VALLEY_STEP = 1.15
"""How much wider (or narrower) a restart along the size-ratio valley starts, as a radius factor."""


def restart_shapes(kind: str, start, fitted) -> tuple | None:
    """The starting shapes of restart ``kind`` (:data:`RESTARTS`) from the ``start`` shapes of a
    fit and its ``fitted`` shapes (:class:`~refine.diagnosis.shapes.RegionShape` or ``Hole``,
    in the same order); None where the restart does not apply (along the valley: a hole, or a
    strength no ratio reaches)."""
    if kind not in RESTARTS:
        raise ValueError(f"unknown restart {kind!r}; use one of {', '.join(RESTARTS)}")
    out = []
    for s, f in zip(start, fitted):
        has_ratio = "ratio" in {x.name for x in fields(f)}
        if kind == "recentred":
            new = replace(s, centre=f.centre)
        else:
            r = float(np.sqrt(f.axes[0] * f.axes[1]))
            new = replace(f, axes=(r, r))
        if has_ratio:
            new = replace(new, ratio=f.ratio)
        if kind in ("larger", "smaller"):
            scale = VALLEY_STEP if kind == "larger" else 1.0 / VALLEY_STEP
            ratio = ratio_along_valley(f.ratio, scale) if has_ratio and f.ratio is not None else None
            if ratio is None:
                return None
            new = replace(new, axes=(scale * r, scale * r), ratio=ratio)
        out.append(new)
    return tuple(out)


def best_of_restarts(f, start, fit_mask, hold_mask, kinds=RESTARTS, pool=None):
    """``f`` (a :class:`~refine.diagnosis.fitted.Fitted` started at the shapes ``start``) or a
    refit of its hypothesis from one of the restarts ``kinds`` (:func:`restart_shapes`),
    whichever has the lowest misfit on ``fit_mask`` (the first of equal ones, in ``kinds``'s
    order). A restart whose shapes all lie within a fifth of an element of the fitted ones or of
    an earlier restart's is skipped (it would settle where that one did); one that cannot be
    fitted is skipped. Costs a fit per restart tried (a recentred one converges in a few steps);
    ``pool`` (an executor, e.g. the diagnosis's): the restarts fitted side by side, the same result."""
    from refine.diagnosis.fitted import fit

    if not (f.shapes and f.hypothesis.remeshable and kinds):
        return f
    tried = [tuple(f.shapes)]
    near = 0.2 * f.model.h
    element = getattr(f.hypothesis, "element", "tri3")
    for kind in kinds:
        shapes = restart_shapes(kind, start, f.shapes)
        if shapes is not None and all(max(a.moved(b) for a, b in zip(shapes, t)) >= near for t in tried):
            tried.append(shapes)

    def attempt(shapes):
        try:
            return fit(f.hypothesis.at(shapes, element), fit_mask, hold_mask, f.sigma)
        except Exception:  # noqa: BLE001 - a restart that cannot be meshed or solved is no better
            return None

    if pool is None:
        refits = [attempt(shapes) for shapes in tried[1:]]
    else:
        refits = [job.result() for job in [pool.submit(attempt, shapes) for shapes in tried[1:]]]
    best = f
    for g in refits:
        if g is not None and np.isfinite(g.chi2_fit) and g.chi2_fit < best.chi2_fit:
            best = g
    return best
