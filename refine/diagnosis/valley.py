"""The size-ratio valley of a region's misfit: a small very stiff region moves the tracked points
much as a larger, less stiff one, and what the data fix is the region's strength, its area times
``(r - 1) / (r + 1)`` (``r`` its relative elasticity), not its area and ratio apart.

A region's effect on the field about it is, to leading order, that of a dipole whose strength is
its area times a contrast that saturates: an ever stiffer region of a given size moves the points
less and less more (``(r - 1) / (r + 1) -> 1``, a rigid region), an ever softer one tends to a
hole (``-> -1``). Along the valley the strength stays nearly constant while the ratio changes
manyfold: the valley is straight in (area, strength) and bends sharply in (area, log ratio), the
fit's own unknowns. So a Gaussian about the fit in its own unknowns, the Gauss-Newton
covariance, follows the valley's tangent and misses its bend: the ratio of a stiff region comes
out with an error far too small on the stiff side, and a fit started on one side of the bend can
stop there (``benchmarks/error_coverage.py`` measures both).
:func:`ratio_draws` gives the ratio's draws with the strength drawn instead of the log ratio
(the same covariance to first order); :func:`ratio_along_valley` restarts a fit along it.
"""

from __future__ import annotations

import numpy as np
from jaxtyping import Float


def contrast(ratio):
    """``(r - 1) / (r + 1)`` of a relative elasticity ``r`` (``tanh(ln r / 2)``): -1 for a hole,
    0 for the background, 1 for a rigid region."""
    r = np.asarray(ratio, float)
    return (r - 1.0) / (r + 1.0)


def ratio_of(strength, area):
    """The relative elasticity of a region of ``area`` and ``strength`` (area x :func:`contrast`):
    ``inf`` where the strength needs a contrast of 1 or more (stiffer than rigid), 0 where -1 or
    less (softer than a hole)."""
    c = np.asarray(strength, float) / np.asarray(area, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = (1.0 + c) / (1.0 - c)
    return np.where(c >= 1.0, np.inf, np.where(c <= -1.0, 0.0, r))


def ratio_draws(q0: Float[np.ndarray, "shapes 7"], q: Float[np.ndarray, "draws shapes 7"],
                G: Float[np.ndarray, "q k"], dz: Float[np.ndarray, "draws k"]) -> Float[np.ndarray, "draws shapes"]:
    """Draws of every shape's ratio with its strength drawn in its stead: the strength to first
    order in the draws ``dz`` of the fitted unknowns (``G``, ``d quantities / dz`` of
    :func:`~refine.diagnosis.uncertainty.quantity_jacobian`, rows in :data:`QUANTITIES` order
    per shape), the area as drawn (``q``, the quantities at each draw, column 5), the ratio from
    both (:func:`ratio_of`). ``q0``: the fitted quantities. A shape with no finite positive
    ratio (a hole) keeps its draws."""
    out = q[..., 6].copy()
    for i, (area, r) in enumerate(q0[:, 5:7]):
        if not (np.isfinite(r) and r > 0 and area > 0):
            continue
        dstrength = contrast(r) * G[7 * i + 5] + area * 2.0 / (r + 1.0) ** 2 * G[7 * i + 6]
        out[:, i] = ratio_of(area * contrast(r) + dz @ dstrength, q[:, i, 5])
    return out


def ratio_along_valley(ratio: float, scale: float) -> float | None:
    """The ratio of a region ``scale`` times as wide (its area ``scale^2`` times) at the same
    strength as one of relative elasticity ``ratio``, or None where no ratio reaches it (a
    smaller region would have to be stiffer than rigid, or softer than a hole)."""
    r = float(ratio_of(contrast(ratio), scale**2))
    return r if 0.0 < r < np.inf else None
