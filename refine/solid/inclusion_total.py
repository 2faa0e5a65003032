"""A fitted inclusion's discretisation error and the total intervals of its ratio, volume and
strength: the profile's statistical intervals widened by the fit mesh's bias.

The profile (:mod:`refine.solid.inclusion_profile`) gives intervals of the fit mesh's own model:
where chi^2 rises by at most 4 x the reduced chi^2, two standard errors of one unknown. They do not
hold what that mesh leaves out: the graded fit mesh (smooth Mori-Tanaka cells over the inclusion)
biases the fit along the volume-ratio valley, the truth's own shape lying well above the least
chi^2 (benchmarks/inclusion3d.py). As the 2D diagnosis
does (:func:`refine.diagnosis.uncertainty.discretisation_bias`), the error is estimated by one refit
of the reported inclusion, from its shape, on the same body graded over the same region with
spacings ``factor`` (sqrt 2) times larger (:func:`discretisation_refit`): Richardson's estimate
``|q_coarser - q_fit| / (factor^order - 1)`` (order 2, the energy norm's rate of quadratic
elements; with sqrt 2 the change itself), the ratio's in its logarithm (the profile's variable).

The total interval (:func:`total_interval`) reads each side of the profile's interval as two
statistical standard errors and adds the discretisation error in quadrature, as
:func:`refine.diagnosis.uncertainty.total_errors` does: a side of half-width ``w`` about the fit
becomes ``sqrt(w^2 + (2 d)^2)``, so it stays two total errors wide and keeps the profile's
asymmetry (a plain ``w + 2 d`` would add the two errors as if always of one sign and size). An
open end (the profile ran to the ratio's bound) stays open.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from refine.solid.inclusion_mesh import FocusedMesh, coarser, refit_focused
from refine.solid.inclusion_profile import strength

COVERAGE = 2.0
"""How many standard errors each side of a total interval spans (the profile's threshold 4 is
two statistical ones)."""


@dataclass(frozen=True)
class Discretisation:
    """The refit on the coarser mesh (``cells``, ``factor`` times the fit mesh's spacings) and the
    discretisation errors it gives (``errors``: ``log_ratio``, ``volume`` (mm^3), ``strength``
    (mm^3); Richardson's for ``order``); the refit's ``values`` (ratio, volume, strength),
    ``evaluations`` and ``seconds``."""

    factor: float
    order: float
    cells: int
    values: dict
    errors: dict
    evaluations: int
    seconds: float

    def as_dict(self) -> dict:
        """report.json's content."""
        return {"factor": self.factor, "order": self.order, "cells": self.cells, "coarser_fit": self.values,
                "errors": self.errors, "evaluations": self.evaluations, "seconds": self.seconds}


def values_of(shape, nu: float) -> dict:
    """The ratio, volume (mm^3) and strength (mm^3) of an :class:`~refine.solid.inclusion.EllipsoidShape`."""
    return {"ratio": float(shape.ratio), "volume": float(shape.volume),
            "strength": float(strength(shape.volume, shape.ratio, nu))}


def errors_between(fit: dict, other: dict, factor: float, order: float) -> dict:
    """Richardson's estimate of the ``fit``'s discretisation errors from ``other`` (the same
    inclusion fitted on a mesh ``factor`` times coarser): ``|other - fit| / (factor^order - 1)``
    of the log ratio, the volume and the strength."""
    k = factor**order - 1.0
    return {"log_ratio": abs(np.log(other["ratio"] / fit["ratio"])) / k,
            "volume": abs(other["volume"] - fit["volume"]) / k,
            "strength": abs(other["strength"] - fit["strength"]) / k}


def discretisation_refit(f, fit_mask, hold_mask, sigma: float, focus: FocusedMesh, region,
                         factor: float = np.sqrt(2.0), order: float = 2.0) -> Discretisation | None:
    """The discretisation error of ``f`` (the reported inclusion fit on the box graded by
    ``focus`` over ``region``) from its refit, started from its shape, on the box graded over the
    same region with spacings ``factor`` times larger (at most ``focus.max_steps`` evaluations);
    None where that mesh cannot be made or the refit fails."""
    t0 = time.perf_counter()
    try:
        _, g = refit_focused(f, fit_mask, hold_mask, sigma, coarser(focus, factor), region=region, with_base=False)
    except Exception:  # noqa: BLE001 - a coarser mesh that cannot hold the shape gives no estimate
        return None
    if g is None or not np.isfinite(g.chi2_fit) or not g.shapes:
        return None
    nu = float(f.model.experiment.nu)
    fit, other = values_of(f.shapes[0], nu), values_of(g.shapes[0], nu)
    n = int(getattr(getattr(g, "result", None), "n_forward", 0) or 0)
    return Discretisation(float(factor), float(order), int(g.model.mesh.n_cells), other,
                          errors_between(fit, other, factor, order), n, time.perf_counter() - t0)


def total_interval(value: float, interval, error: float, log: bool = False, coverage: float = COVERAGE
                   ) -> tuple[float, float]:
    """The statistical ``interval`` ``(low, high)`` about the fitted ``value`` with the
    discretisation ``error`` added (see the module): each side's half-width ``w`` becomes
    ``sqrt(w^2 + (coverage error)^2)``; ``log``: in the logarithm (the ratio: ``error`` is of its
    log)."""
    f = (lambda x: np.log(x)) if log else (lambda x: x)
    g = (lambda x: float(np.exp(x))) if log else float
    v, lo, hi = f(value), f(interval[0]), f(interval[1])
    e = coverage * float(error)
    return g(v - np.hypot(max(v - lo, 0.0), e)), g(v + np.hypot(max(hi - v, 0.0), e))


def total_intervals(fit: dict, profile: dict, disc: Discretisation | None) -> dict:
    """report.json's ``total``: per quantity (ratio, volume, strength) the profile's interval
    about the ``fit``'s values widened by ``disc``'s errors (:func:`total_interval`); the ratio's
    open ends stay at the profile's (open); without ``disc`` the profile's intervals as they are,
    ``discretisation`` False."""
    if disc is None:
        return {"ratio": list(profile["ratio"]), "volume": list(profile["volume"]),
                "strength": list(profile["strength"]), "open": list(profile["open"]), "discretisation": False,
                "rule": "no discretisation error estimated: the profile's statistical intervals"}
    e = disc.errors
    ratio = list(total_interval(fit["ratio"], profile["ratio"], e["log_ratio"], log=True))
    ratio = [profile["ratio"][k] if profile["open"][k] else ratio[k] for k in (0, 1)]
    volume = total_interval(fit["volume"], profile["volume"], e["volume"])
    return {"ratio": ratio, "volume": [max(volume[0], 0.0), volume[1]],  # a volume is not negative
            "strength": list(total_interval(fit["strength"], profile["strength"], e["strength"])),
            "open": list(profile["open"]), "discretisation": True,
            "rule": f"each side of the profile's interval about the fit (2 statistical errors) and {COVERAGE:g} "
                    "discretisation errors in quadrature (the ratio's in its log)"}
