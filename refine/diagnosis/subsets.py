"""What DIC subsets tell of a hole: a tracked point is the centre of a square subset (side
``subset``, the bundle's ``measurement.subset``) that was correlated, so the whole square lay on
material; a lattice site without a point is a subset that could not be correlated (it met the hole,
or failed otherwise). A hole therefore keeps at least half a subset away from every tracked point
(:func:`seen_material`: samples of the squares a hole hypothesis must not cover), and its edge
lies between the squares that were correlated and those that were not
(:func:`hole_from_subsets`: the ellipse that best separates the two sets).

Lengths in the bundle's unit; a subset is the square ``[x - s/2, x + s/2] x [y - s/2, y + s/2]``
around a point (DIC subsets are axis-aligned squares of pixels).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage, optimize

from tracking import regular_lattice

SAMPLES_PER_SIDE = 6
"""Samples along each side of a subset's square: a curve of radius R can dip between two samples
``s / SAMPLES_PER_SIDE`` apart by (s / SAMPLES_PER_SIDE)^2 / (8 R), 0.02 px for a 21-px subset
and a 50-px hole."""

DIRECTIONS = 180
"""Normal directions over a full turn at which the support functions are compared."""


def seen_material(points: np.ndarray, subset: float | None) -> np.ndarray:
    """Places a hole may not cover, ``(m, 2)``: the tracked ``points`` ``(n, 2)`` themselves and,
    where the ``subset`` side is known, samples of every point's square subset outline (its
    corners included), so that a hole keeps half a subset away from each point."""
    pts = np.asarray(points, float)[:, :2]
    if subset is None:
        return pts
    r = 0.5 * float(subset)
    t = np.linspace(-r, r, SAMPLES_PER_SIDE + 1)
    ring = np.concatenate([np.c_[t, np.full_like(t, -r)], np.c_[t, np.full_like(t, r)],
                           np.c_[np.full_like(t, -r), t], np.c_[np.full_like(t, r), t]])
    ring = np.unique(np.round(ring, 12), axis=0)
    return np.concatenate([pts, (pts[:, None, :] + ring[None]).reshape(-1, 2)])


@dataclass(frozen=True)
class Lattice:
    """A regular axis-aligned lattice of correlation sites: ``origin + (col, row) * step``."""

    origin: np.ndarray
    step: np.ndarray
    index: np.ndarray  # (n, 2) (row, col) of each tracked point

    def sites(self, index: np.ndarray) -> np.ndarray:
        """Positions ``(k, 2)`` of lattice sites ``(k, 2)`` (row, col)."""
        return self.origin + np.asarray(index)[:, ::-1] * self.step


def lattice_of(points: np.ndarray, tol: float = 1e-3) -> Lattice | None:
    """The regular lattice the tracked ``points`` ``(n, 2)`` were correlated on (a tracker's or a
    DIC code's step, :func:`tracking.regular_lattice`), or None where they lie on none (within
    ``tol`` of a step)."""
    lattice = regular_lattice(points, tol)
    return None if lattice is None else Lattice(*lattice)


def untracked_sites(lattice: Lattice) -> np.ndarray:
    """Lattice sites ``(k, 2)`` (positions) enclosed by tracked points but without one: gaps of
    the lattice that do not reach its outer edge (a hole, or subsets that failed inside)."""
    shape = lattice.index.max(axis=0) + 3
    tracked = np.zeros(shape, bool)
    tracked[lattice.index[:, 0] + 1, lattice.index[:, 1] + 1] = True
    gaps, _ = ndimage.label(~tracked)
    outer = np.unique(np.concatenate([gaps[0], gaps[-1], gaps[:, 0], gaps[:, -1]]))
    inner = (gaps > 0) & ~np.isin(gaps, outer)
    return lattice.sites(np.argwhere(inner) - 1)


def subset_distance(sites: np.ndarray, params, subset: float) -> np.ndarray:
    """Signed distance ``(k,)`` from each site to the ellipse ``params`` ``(cx, cy, a, b,
    angle)`` grown by a square subset of side ``subset`` (positive: the site's subset misses the
    ellipse; negative: it overlaps it). The grown set is convex, its support function the sum of
    the ellipse's and the square's, and a convex set's signed distance is the largest of
    ``n . p - h(n)`` over unit normals n (sampled at :data:`DIRECTIONS`)."""
    cx, cy, a, b, angle = params
    t = np.linspace(0, 2 * np.pi, DIRECTIONS, endpoint=False)
    n = np.c_[np.cos(t), np.sin(t)]
    c, s = np.cos(angle), np.sin(angle)
    h_ellipse = np.hypot(a * (n @ [c, s]), b * (n @ [-s, c]))
    h_square = 0.5 * subset * (np.abs(n[:, 0]) + np.abs(n[:, 1]))
    p = np.asarray(sites, float)[:, :2] - [cx, cy]
    return np.max(p @ n.T - (h_ellipse + h_square)[None], axis=1)


@dataclass(frozen=True)
class SubsetEvidence:
    """The hole the subsets show: ``params`` ``(cx, cy, a, b, angle)`` of the ellipse that best
    separates correlated from uncorrelated subsets, ``tracked`` and ``untracked`` the sites
    weighed, ``misclassified`` how many lie on the wrong side of it."""

    params: np.ndarray
    tracked: np.ndarray
    untracked: np.ndarray
    misclassified: int


def hole_from_subsets(points: np.ndarray, subset: float, centre, reach: float) -> SubsetEvidence | None:
    """The hole shown by the subsets around ``centre`` (a candidate's, length unit): the lattice
    gap nearest ``centre`` (within ``reach``) and the tracked points within a few lattice steps
    of it; the ellipse grown by a subset (:func:`subset_distance`) that puts the gap's sites inside
    and the tracked points outside, each with a logistic weight of its signed distance over a
    quarter lattice step (the edge lies anywhere between the last correlated and the first failed
    subset: the fit takes the middle). None where the points lie on no lattice or no gap lies
    within ``reach``."""
    lattice = lattice_of(points)
    if lattice is None:
        return None
    gaps = untracked_sites(lattice)
    if not len(gaps):
        return None
    step = float(lattice.step.max())
    near = np.hypot(*(gaps - np.asarray(centre)).T) <= reach
    if not near.any():
        return None
    # the gap's connected part around the candidate (sites a step apart)
    part = np.zeros(len(gaps), bool)
    part[np.flatnonzero(near)[np.argmin(np.hypot(*(gaps[near] - np.asarray(centre)).T))]] = True
    while True:
        d = np.min(np.hypot(*(gaps[:, None] - gaps[part][None]).transpose(2, 0, 1)), axis=1)
        grown = part | (d <= 1.5 * step)
        if grown.sum() == part.sum():
            break
        part = grown
    inside = gaps[part]
    pts = np.asarray(points, float)[:, :2]
    d_pts = np.min(np.hypot(*(pts[:, None] - inside[None]).transpose(2, 0, 1)), axis=1)
    outside = pts[d_pts <= 3 * step]
    lo, hi = inside.min(axis=0), inside.max(axis=0)
    start = np.array([*(0.5 * (lo + hi)), *np.maximum(0.5 * (hi - lo) - 0.5 * subset, 0.5 * step), 0.0])
    tau = 0.25 * step

    def loss(q):
        q = np.r_[q[:2], np.abs(q[2:4]) + 1e-6, q[4]]
        return (np.logaddexp(0, -subset_distance(outside, q, subset) / tau).sum()
                + np.logaddexp(0, subset_distance(inside, q, subset) / tau).sum())

    best = optimize.minimize(loss, start, method="Nelder-Mead",
                             options={"xatol": 1e-3 * step, "fatol": 1e-6, "maxiter": 4000})
    q = np.r_[best.x[:2], np.abs(best.x[2:4]), best.x[4]]
    wrong = int((subset_distance(outside, q, subset) <= 0).sum() + (subset_distance(inside, q, subset) > 0).sum())
    return SubsetEvidence(q, outside, inside, wrong)
