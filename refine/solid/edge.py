"""What a painted grid's crossings tell of a hole's edge: the crossings of a square grid form a
lattice (any orientation; the grid is painted at any angle), a crossing inside a hole does not
exist, so the lattice sites missing inside the floor lie in the hole (or on its very edge, where a
crossing's lines are cut and it is lost), and every tracked crossing lies outside it. The missing
sites and the tracked points beside them bracket the hole's outline within a grid step.

Only gaps enclosed by tracked crossings count (:func:`evidence_near`: a gap of missing sites
that does not reach the lattice's outline): a crossing lost
at the rim, or a part of the bottom out of view, reaches the lattice's outline and is no evidence
of a hole.

Lengths in the bundle's unit (mm); points ``(n, 2)`` in the plane of the face (the cup's frame).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from refine.diagnosis.subsets import hole_from_subsets, subset_distance
from refine.model.parametrize import ShapeGeometry
from tracking import regular_lattice


class NoLattice(ValueError):
    """The points lie on no square lattice (within a quarter step): no edge evidence."""


@dataclass(frozen=True)
class GridLattice:
    """A square lattice ``origin + step * R(angle) (col, row)``: ``origin (2,)``, ``step``
    (length unit), ``angle`` (rad), and each tracked point's ``index (n, 2)`` (row, col)."""

    origin: np.ndarray
    step: float
    angle: float
    index: np.ndarray

    def sites(self, index) -> np.ndarray:
        """Positions ``(k, 2)`` of lattice sites ``index (k, 2)`` (row, col)."""
        return from_lattice(self, np.asarray(index, float)[:, ::-1])


def grid_lattice(points, tol: float = 0.25) -> GridLattice:
    """The square lattice of tracked grid crossings ``points (n, 2)`` (noisy positions, any
    orientation): the orientation and step from the nearest neighbours' offsets, each point's
    (row, col) by rounding in the lattice's frame (there :func:`tracking.regular_lattice` finds the
    origin and indices of the snapped points), origin and step refitted by least squares. Raises
    :class:`NoLattice` where a point lies more than ``tol`` steps off its site or two share one."""
    xy = np.asarray(points, float)[:, :2]
    if len(xy) < 9:
        raise NoLattice(f"{len(xy)} points are too few to show a lattice")
    d, j = cKDTree(xy).query(xy, k=5)
    step0 = float(np.median(d[:, 1]))
    v = (xy[j[:, 1:]] - xy[:, None]).reshape(-1, 2)
    near = np.abs(np.linalg.norm(v, axis=1) / step0 - 1) < 0.25
    if near.sum() < len(xy):
        raise NoLattice("the points' nearest neighbours are not a grid's")
    four = np.arctan2(v[near, 1], v[near, 0]) * 4  # a square lattice's offsets agree modulo a quarter turn
    angle = float(np.arctan2(np.sin(four).mean(), np.cos(four).mean()) / 4)
    c, s = np.cos(angle), np.sin(angle)
    local = xy @ np.array([[c, -s], [s, c]]) / step0  # the lattice's frame, unit step
    frac = 2 * np.pi * local
    shift = np.arctan2(np.sin(frac).mean(0), np.cos(frac).mean(0)) / (2 * np.pi)
    snapped = np.rint(local - shift)
    lattice = regular_lattice(snapped + 0.5, tol=1e-6)  # on snapped integers: exact
    if lattice is None:
        raise NoLattice("the points lie on no lattice")
    _, _, index = lattice
    # least squares: xy = origin + step * R (col, row)
    A = np.zeros((2 * len(xy), 4))
    cr = index[:, ::-1].astype(float) @ np.array([[c, s], [-s, c]])
    A[0::2, 0], A[1::2, 1], A[0::2, 2], A[1::2, 2] = 1.0, 1.0, cr[:, 0], cr[:, 1]
    sol = np.linalg.lstsq(A, xy.reshape(-1), rcond=None)[0]
    out = GridLattice(sol[:2], float(sol[2]), angle, index)
    off = np.linalg.norm(out.sites(index) - xy, axis=1) / out.step
    if off.max() > tol or len({tuple(r) for r in index}) < len(index):
        raise NoLattice(f"a point lies {off.max():.2f} steps off its lattice site, or two share one")
    return out


def to_lattice(lattice: GridLattice, xy) -> np.ndarray:
    """Points ``(k, 2)`` (cup frame) in the lattice's frame: unit step, sites at integers (col, row)."""
    c, s = np.cos(lattice.angle), np.sin(lattice.angle)
    return (np.asarray(xy, float).reshape(-1, 2) - lattice.origin) @ np.array([[c, -s], [s, c]]) / lattice.step


def from_lattice(lattice: GridLattice, uv) -> np.ndarray:
    """Points ``(k, 2)`` of the lattice's frame back in the cup's frame."""
    c, s = np.cos(lattice.angle), np.sin(lattice.angle)
    return lattice.origin + lattice.step * np.asarray(uv, float).reshape(-1, 2) @ np.array([[c, s], [-s, c]])


@dataclass(frozen=True)
class EdgeEvidence:
    """The grid's evidence of one hole (cup frame): the ``missing`` sites ``(k, 2)`` of its gap,
    the ``tracked`` points ``(m, 2)`` around it, the lattice ``step``, ``slack`` (length unit):
    how far outside the hole a missing site may lie (a crossing on the hole's edge is lost too),
    and ``ellipse`` ``(cx, cy, a, b, angle)``: the one between the two sets (a fit's start)."""

    missing: np.ndarray
    tracked: np.ndarray
    step: float
    slack: float
    ellipse: np.ndarray

    def violation(self, ellipse) -> float:
        """How far (length unit) the ellipse ``(cx, cy, a, b, angle)`` breaks the evidence: the
        largest distance by which a missing site lies outside it beyond ``slack``, or a tracked
        point inside it (0: consistent)."""
        d_miss = subset_distance(self.missing, ellipse, 0.0)
        d_tracked = subset_distance(self.tracked, ellipse, 0.0)
        return float(max(0.0, (d_miss - self.slack).max(initial=0.0), (-d_tracked).max(initial=0.0)))

    def missing_outside(self, ellipse) -> float:
        """The largest distance (length unit) by which a missing site lies outside the ellipse."""
        return float(subset_distance(self.missing, ellipse, 0.0).max())

    def area_range(self, start=None) -> tuple[float, float] | None:
        """The smallest and largest area (length unit^2) of an ellipse consistent with the evidence
        (:meth:`violation` 0), searched from ``start`` (default :attr:`ellipse`; a consistent one,
        e.g. a fitted hole, is best): what the grid alone says of the hole's area. None where the
        search finds no consistent ellipse (SLSQP stopped outside the constraints)."""
        from scipy import optimize

        cons = [{"type": "ineq", "fun": lambda q: self.slack - subset_distance(self.missing, q, 0.0)},
                {"type": "ineq", "fun": lambda q: subset_distance(self.tracked, q, 0.0)}]
        q0 = np.asarray(self.ellipse if start is None else start, float)
        out = []
        for sign in (1.0, -1.0):
            r = optimize.minimize(lambda q: sign * q[2] * q[3], q0, constraints=cons, method="SLSQP",
                                  options={"maxiter": 200})
            q = np.r_[r.x[:2], np.abs(r.x[2:4]), r.x[4]]
            if self.violation(q) > 1e-3 * self.step:
                return None
            out.append(float(np.pi * q[2] * q[3]))
        return out[0], out[1]


def evidence_near(lattice: GridLattice, centre, reach: float, floor: float,
                  slack: float = 0.75) -> EdgeEvidence | None:
    """The grid's evidence of a hole near ``centre`` (cup frame, within ``reach``): in the
    lattice's frame, where the tracked crossings sit on integer sites,
    :func:`refine.diagnosis.subsets.hole_from_subsets` (points, no subset) finds the gap of
    missing sites enclosed by tracked ones (a gap that reaches the lattice's outline, a crossing
    lost at the rim or a part out of view, is none) nearest ``centre``, the tracked points around
    it and the ellipse between them. Only missing sites inside the floor (radius ``floor``, where a
    hole can be) count. ``slack``: steps a missing site may lie outside the hole. None where no
    such gap lies within ``reach``."""
    sites = lattice.index[:, ::-1].astype(float)
    found = hole_from_subsets(sites, 0.0, to_lattice(lattice, centre)[0], reach / lattice.step)
    if found is None:
        return None
    missing = from_lattice(lattice, found.untracked)
    missing = missing[np.hypot(*missing.T) < floor]
    if not len(missing):
        return None
    cx, cy, a, b, angle = found.params
    centre = from_lattice(lattice, [[cx, cy]])[0]
    ellipse = np.r_[centre, a * lattice.step, b * lattice.step, angle + lattice.angle]
    return EdgeEvidence(missing, from_lattice(lattice, found.tracked), lattice.step, slack * lattice.step, ellipse)


@dataclass(frozen=True, eq=False)
class EdgeGeometry(ShapeGeometry):
    """A hole's geometry (:class:`refine.model.parametrize.ShapeGeometry`, which keeps it off every
    tracked point) that also keeps every missing site of ``edge`` within ``slack`` (length unit;
    at least the edge's own, more where the start leaves a site farther out) of the hole: a step
    that would move the hole away from its gap is turned down before any solve."""

    edge: EdgeEvidence | None = None
    slack: float = 0.0

    def constraints(self, z) -> np.ndarray:
        """Values ``>= 0`` where the hole at ``z`` keeps off the tracked points near it (by a
        hundredth of ``scale``), keeps its gap's missing sites within the slack and both semi-axes
        above ``min_axis``; cheap (no solve): the fit's steps slide along them
        (:func:`refine.optimize.levenberg_marquardt.constrained_step`)."""
        p = self.shape_params(z)[0]
        margin = max(self.min_axis, 1e-3 * self.scale)
        out = [p[2:4] - margin]
        if self.outside is not None and len(self.outside):
            d = subset_distance(self.outside, p, 0.0)
            out.append(np.sort(d)[:64] - 0.01 * self.scale)  # those a step can reach
        if self.edge is not None:
            out.append(self.slack - subset_distance(self.edge.missing, p, 0.0))
        return np.concatenate(out)

    def infeasibility(self, z) -> str | None:
        why = super().infeasibility(z)
        if why or self.edge is None:
            return why
        for p in self.shape_params(z):
            out = self.edge.missing_outside(p)
            if out > self.slack:
                return f"a missing crossing would lie {out:.2f} outside the hole"
        return None
