"""A domain's outline built from the tracked points themselves (``domain = { from_points = ... }``).

Measured points never lie on a drawn line: a specimen's edge, seen by DIC, is a ragged row of
points. Rather than ask the user for an outline that the boundary points only approximately
follow, the outline can be made from the points: their concave outline (an alpha shape: the
union of the Delaunay triangles of all points whose edges are at most ``max_edge`` long) or
their convex hull, then made to pass through every boundary point (each is placed, in order,
where it projects onto that outline), so that the points that drive the model lie exactly on
the model's outline and every other point inside it. Gaps inside (a hole without points) stay
material: finding them is the diagnosis's job; known holes are cut as for any domain.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.spatial import ConvexHull, Delaunay

from refine.bundle.experiment import Experiment, FromPointsDomain, PolygonDomain
from refine.bundle.observations import Observations
from refine.bundle.roles import point_spacing
from refine.exceptions import ObservationError

MAX_EDGE = 2.5  # default longest edge of the concave outline, in point spacings


def resolve_domain(experiment: Experiment, obs: Observations) -> Experiment:
    """``experiment`` with a :class:`FromPointsDomain` replaced by the :class:`PolygonDomain` it
    makes from ``obs`` (same holes and sides); any other domain is returned unchanged."""
    dom = experiment.domain
    if not isinstance(dom, FromPointsDomain):
        return experiment
    vertices = outline_of_points(obs.reference, obs.roles == "boundary", dom.outline, dom.max_edge, obs.ids)
    return replace(experiment, domain=PolygonDomain(tuple(map(tuple, vertices)), holes=dom.holes, sides=dom.sides))


def outline_of_points(points, boundary, outline: str = "concave", max_edge: float | None = None,
                      ids=None) -> np.ndarray:
    """The outline of ``points (n, 2)`` through every boundary point, ``(m, 2)`` counter-clockwise.

    Args:
        points: reference positions, length unit.
        boundary: ``(n,)`` bool, the points that drive the model (all of them lie on the outline).
        outline: ``"concave"`` (alpha shape) or ``"convex"`` (hull).
        max_edge: longest edge of the concave outline, length unit (None: 2.5 point spacings).
        ids: point ids for error messages.

    Raises:
        ObservationError: fewer than 3 points, points off the outline's one piece, an outline
            through the boundary points that crosses itself, or a point left outside it.
    """
    pts = np.asarray(points, np.float64)
    boundary = np.asarray(boundary, bool)
    ids = np.arange(len(pts)) if ids is None else np.asarray(ids)
    if len(pts) < 3:
        raise ObservationError(f"an outline from points needs at least 3 points, got {len(pts)}")
    if outline == "convex":
        hull = ConvexHull(pts).vertices  # counter-clockwise
    else:
        hull = _concave(pts, (max_edge or MAX_EDGE * point_spacing(pts)), ids)
    ring = pts[hull]
    arc, dist = _project(ring, pts)
    on = np.zeros(len(pts), bool)
    on[hull] = True
    members = np.flatnonzero(on | boundary)
    members = members[np.lexsort((dist[members], arc[members]))]  # along the outline; a point on it first
    poly = pts[members]
    crossing = _self_crossing(poly)
    if crossing is not None:
        a, b = members[crossing], members[(crossing + 1) % len(members)]
        raise ObservationError(
            f"the outline through the boundary points crosses itself near points {ids[a]} and {ids[b]} "
            f"(at {pts[a].round(3).tolist()}); check which points are marked boundary there, or give the domain "
            "as a polygon or rectangle")
    outside = ~on & ~boundary & ~_inside(poly, pts)
    if outside.any():
        _, d = _project(poly, pts)
        worst = np.flatnonzero(outside)[np.argmax(d[outside])]
        raise ObservationError(
            f"{int(outside.sum())} points lie outside the outline through the boundary points (the farthest, point "
            f"{ids[worst]}, by {d[worst]:.3g}); mark the outermost points of each edge as boundary points")
    return poly


def _concave(pts: np.ndarray, max_edge: float, ids) -> np.ndarray:
    """Indices of the alpha shape's outer outline, counter-clockwise."""
    tri = Delaunay(pts).simplices
    a, b, c = (pts[tri[:, k]] for k in range(3))
    longest = np.max([np.linalg.norm(a - b, axis=1), np.linalg.norm(b - c, axis=1),
                      np.linalg.norm(c - a, axis=1)], axis=0)
    keep = tri[longest <= max_edge]
    if not len(keep):
        raise ObservationError(f"no triangle of the points has edges shorter than max_edge = {max_edge:.3g}; "
                               "give a larger domain.max_edge")
    cross = _cross(pts[keep[:, 1]] - pts[keep[:, 0]], pts[keep[:, 2]] - pts[keep[:, 0]])
    keep[cross < 0] = keep[cross < 0][:, ::-1]  # counter-clockwise triangles
    edges = {(int(p), int(q)) for t in keep for p, q in zip(t, np.roll(t, -1))}
    leaving: dict = {}
    for p, q in edges:
        if (q, p) not in edges:  # on the outline: the material on its left
            leaving.setdefault(p, []).append(q)
    # keep to one piece at a pinch: the sharpest left turn
    loops = [np.array(lp) for lp in walk_loops(leaving, lambda p, q: pts[q] - pts[p], _turn)]
    outer = max(loops, key=lambda lp: _area(pts[lp]))
    covered = np.zeros(len(pts), bool)
    covered[np.unique(keep)] = True
    covered &= _inside(pts[outer], pts) | np.isin(np.arange(len(pts)), outer)
    if not covered.all():
        bad = ids[~covered]
        raise ObservationError(
            f"{len(bad)} points lie apart from the others' outline (e.g. {bad[:5].tolist()}): farther than max_edge = "
            f"{max_edge:.3g} from the rest; give a larger domain.max_edge or remove them")
    return outer


def walk_loops(leaving: dict, vector, turn) -> list[list]:
    """Closed loops of directed boundary edges (``leaving``: vertex -> the vertices its edges go to;
    emptied): from the smallest vertex left, each step takes the edge ``turn(heading, vector(here,
    next))`` ranks highest (the heading None at a loop's start), until the loop closes."""
    loops = []
    while leaving:
        start = min(leaving)
        loop, here, heading = [start], start, None
        while True:
            nexts = leaving[here]
            step = max(nexts, key=lambda b: turn(heading, vector(here, b)))
            nexts.remove(step)
            if not nexts:
                del leaving[here]
            heading, here = vector(here, step), step
            if here == start or here not in leaving:
                break
            loop.append(here)
        loops.append(loop)
    return loops


def _turn(heading, direction) -> float:
    if heading is None:
        return 0.0
    return float(np.arctan2(_cross(heading, direction), np.dot(heading, direction)))


def _cross(u, v):
    return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]


def _area(ring: np.ndarray) -> float:
    return 0.5 * float(np.sum(_cross(ring, np.roll(ring, -1, axis=0))))


def _project(ring: np.ndarray, pts: np.ndarray):
    """Arc length of each point's projection on the closed polyline ``ring``, and its distance."""
    seg = np.roll(ring, -1, axis=0) - ring
    L = np.linalg.norm(seg, axis=1)
    s0 = np.concatenate([[0.0], np.cumsum(L)[:-1]])
    arc, dist = np.empty(len(pts)), np.full(len(pts), np.inf)
    for j in range(len(ring)):  # per segment, vectorised over points
        t = np.clip((pts - ring[j]) @ seg[j] / max(L[j] ** 2, 1e-300), 0.0, 1.0)
        d = np.linalg.norm(pts - ring[j] - t[:, None] * seg[j], axis=1)
        better = d < dist
        dist[better], arc[better] = d[better], s0[j] + t[better] * L[j]
    return arc, dist


def _inside(ring: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Whether each point lies inside the closed polygon ``ring`` or on its edges."""
    from matplotlib.path import Path

    _, d = _project(ring, pts)
    return Path(ring).contains_points(pts) | (d <= 1e-9 * np.ptp(ring, axis=0).max())


def _self_crossing(poly: np.ndarray) -> int | None:
    """Index i of an edge (i, i+1) that crosses another non-adjacent edge of the closed polygon, or None."""
    a, b = poly, np.roll(poly, -1, axis=0)
    n = len(poly)
    for i in range(n):
        j = np.arange(i + 2, n if i else n - 1)  # non-adjacent edges after i
        if not len(j):
            continue
        d1 = _cross(b[i] - a[i], a[j] - a[i])
        d2 = _cross(b[i] - a[i], b[j] - a[i])
        d3 = _cross(b[j] - a[j], a[i] - a[j])
        d4 = _cross(b[j] - a[j], b[i] - a[j])
        if np.any((d1 * d2 < 0) & (d3 * d4 < 0)):
            return i
    return None
