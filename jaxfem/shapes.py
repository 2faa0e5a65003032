"""Plates with elliptic or rectangular holes and inclusions, meshed with element edges on every
curve, and a differentiable morph of those curves for geometry fitting.

:func:`plate` (or :func:`domain` for a polygon or elliptic outline) samples every curve with a
spacing set by the target size ``h``, the curvature and the gap to the nearest other curve, fills
the inside with a graded equilateral lattice, and builds a boundary-conforming Delaunay
triangulation (scipy) improved by a few distmesh-like spring steps. Curve nodes lie exactly on the
curves, so the area of a hole or an inclusion converges as O(h^2) with ``tri3``; ``tri6`` and
``quad4`` put their mid-edge nodes on the curves too (O(h^4) area error with ``tri6``).

:func:`morph` prepares a JAX-differentiable map from new shape parameters ``(cx, cy, a, b, angle)``
to node coordinates; :func:`check_morph` says whether a morphed mesh is valid and, if not, by how
much to reduce the change.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from matplotlib.path import Path
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import Delaunay, cKDTree

from . import _config  # noqa: F401  (float64)
from .errors import InvertedElementError, MeshError
from .mesh import Mesh, check_orientation, to_quadratic

_TURN = np.pi / 6  # a chord turns by at most 30 degrees: >= 12 nodes on any circle of curvature
_GRADING = 0.3  # element size grows by at most this much per unit distance from a fine curve
_KEEP_OFF = 0.75  # lattice points closer than this many local sizes to a curve node are dropped
_ROUNDS, _STEPS = 3, 8  # rounds of Delaunay + spring smoothing, and spring steps per round


def _frame(p, xp=np):
    """Centre ``(..., 2)`` and ``A = R(angle) diag(a, b)`` ``(..., 2, 2)`` of parameters ``(..., 5)``
    (``xp`` is numpy, or jax.numpy for the differentiable morph)."""
    c, s = xp.cos(p[..., 4]), xp.sin(p[..., 4])
    rot = xp.stack([xp.stack([c, -s], -1), xp.stack([s, c], -1)], -2)
    return p[..., :2], rot * p[..., None, 2:4]


# ====================================================================== shapes
class _Affine:
    """A shape ``x = c + A xi`` with ``xi`` in the unit ball of the ``_ord`` norm (the unit disc
    for an ellipse, ``[-1, 1]^2`` for a rectangle); its morph moves ``c`` and ``A``."""

    _ord = 2.0
    _max_size = np.inf

    def to_unit(self, x: np.ndarray) -> np.ndarray:
        """Unit-shape coordinates ``xi`` ``(n, 2)`` of points ``x`` ``(n, 2)``."""
        c, A = _frame(self.params)
        return np.linalg.solve(A, (np.asarray(x, float) - c).T).T

    def _from_unit(self, xi):
        c, A = _frame(self.params)
        return c + xi @ A.T

    def contains(self, x: np.ndarray) -> np.ndarray:
        """Whether points ``(n, 2)`` are strictly inside, ``(n,)`` bool."""
        return np.linalg.norm(self.to_unit(x), self._ord, axis=1) < 1

    def to_curve(self, x: np.ndarray) -> np.ndarray:
        """Points ``(n, 2)`` moved radially (in unit coordinates) onto the boundary curve."""
        xi = self.to_unit(x)
        return self._from_unit(xi / np.maximum(np.linalg.norm(xi, self._ord, axis=1), 1e-300)[:, None])


@dataclass(frozen=True)
class Ellipse(_Affine):
    """Ellipse with centre ``(cx, cy)`` and semi-axes ``rx``, ``ry`` (length units), its ``rx`` axis
    turned ``angle`` radians counter-clockwise from x."""

    cx: float
    cy: float
    rx: float
    ry: float
    angle: float = 0.0

    def __post_init__(self):
        if not (self.rx > 0 and self.ry > 0):
            raise MeshError(f"an ellipse needs positive semi-axes, got rx={self.rx}, ry={self.ry}")

    @property
    def params(self) -> np.ndarray:
        """``(cx, cy, rx, ry, angle)``, the morph parameters."""
        return np.array([self.cx, self.cy, self.rx, self.ry, self.angle], float)

    @property
    def area(self) -> float:
        return float(np.pi * self.rx * self.ry)

    def _pieces(self, h):
        """One dense closed polyline ``(k, 2)`` and its radius of curvature ``(k,)``."""
        a, b = self.rx, self.ry
        perimeter = np.pi * (3 * (a + b) - np.sqrt((3 * a + b) * (a + 3 * b)))
        n = np.clip(max(64 * max(a, b) / min(a, b), 8 * perimeter / h), 2048, 2**17)  # resolve sharp ends
        t = np.linspace(0, 2 * np.pi, int(n) + 1)
        speed = np.hypot(a * np.sin(t), b * np.cos(t))
        return [(self._from_unit(np.stack([np.cos(t), np.sin(t)], -1)), speed**3 / (a * b))]


@dataclass(frozen=True)
class Rect(_Affine):
    """Rectangle ``[x0, x1] x [y0, y1]`` (length units), turned ``angle`` radians counter-clockwise
    about its centre."""

    x0: float
    y0: float
    x1: float
    y1: float
    angle: float = 0.0
    _ord = np.inf

    def __post_init__(self):
        if not (self.x1 > self.x0 and self.y1 > self.y0):
            raise MeshError(f"a rectangle needs x1 > x0 and y1 > y0, got {self}")

    @property
    def params(self) -> np.ndarray:
        """``(cx, cy, half width, half height, angle)``, the morph parameters."""
        return np.array([(self.x0 + self.x1) / 2, (self.y0 + self.y1) / 2, (self.x1 - self.x0) / 2,
                         (self.y1 - self.y0) / 2, self.angle], float)

    @property
    def area(self) -> float:
        return float((self.x1 - self.x0) * (self.y1 - self.y0))

    @property
    def _max_size(self):  # at least one element across a thin rectangle
        return min(self.x1 - self.x0, self.y1 - self.y0)

    def _pieces(self, h):
        return _polygon_pieces(self._from_unit(np.array([[-1.0, -1], [1, -1], [1, 1], [-1, 1]])), h)


@dataclass(frozen=True, eq=False)
class Polygon:
    """Simple polygon with vertices ``(m, 2)`` (length units); an outline or a hole, not morphable."""

    vertices: np.ndarray
    _max_size = np.inf

    def __post_init__(self):
        v = np.asarray(self.vertices, float)
        if v.ndim != 2 or v.shape[1] != 2 or len(v) < 3:
            raise MeshError(f"a polygon needs vertices of shape (m >= 3, 2), got {v.shape}")
        object.__setattr__(self, "vertices", v)

    @property
    def area(self) -> float:
        x, y = self.vertices.T
        return float(abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))) / 2)

    def contains(self, x):
        return Path(self.vertices).contains_points(x)

    def to_curve(self, x):
        """Closest points ``(n, 2)`` on the sides."""
        a, b = self.vertices, np.roll(self.vertices, -1, axis=0)
        s = np.clip(np.einsum("nmi,mi->nm", x[:, None] - a, b - a) / ((b - a) ** 2).sum(1), 0, 1)
        p = a + s[..., None] * (b - a)  # (n, m, 2)
        return p[np.arange(len(x)), np.linalg.norm(p - x[:, None], axis=2).argmin(1)]

    def _pieces(self, h):
        return _polygon_pieces(self.vertices, h)


def _polygon_pieces(v, h):
    """Each side as a dense polyline with an infinite radius of curvature."""
    out = []
    for a, b in zip(v, np.roll(v, -1, axis=0)):
        s = np.linspace(0, 1, int(np.clip(8 * np.linalg.norm(b - a) / h, 16, 20000)) + 1)[:, None]
        out.append((a + s * (b - a), np.full(len(s), np.inf)))
    return out


# ====================================================================== meshing
def plate(x0: float, y0: float, x1: float, y1: float, h: float, holes=(), inclusions=(),
          element: str = "tri3") -> Mesh:
    """Mesh of the rectangle ``[x0, x1] x [y0, y1]`` minus ``holes``, with ``inclusions`` tagged;
    see :func:`domain`."""
    return domain(Rect(x0, y0, x1, y1), h, holes, inclusions, element)


def domain(outline, h: float, holes=(), inclusions=(), element: str = "tri3") -> Mesh:
    """Mesh of the inside of ``outline`` minus ``holes``, element edges following every curve.

    Args:
        outline: a :class:`Rect`, :class:`Ellipse` or :class:`Polygon`.
        h: target element edge length (length units); it is reduced automatically where a curve is
            sharply bent (>= 12 elements per circle of curvature) or close to another curve.
        holes: shapes removed from the domain.
        inclusions: shapes meshed and tagged 1, 2, ... in the order given (``region_names``
            ``"inclusion1"``...), or a dict ``{name: shape}``.
        element: ``"tri3"``, ``"tri6"`` (mid-edge nodes on the curves) or ``"quad4"`` (each
            triangle of size 2h split into three quadrilaterals).

    Returns:
        A :class:`Mesh` with nodes ``(n, 2)``; :func:`curve_nodes` gives the nodes on a curve.

    Raises:
        MeshError: shapes overlap, touch or leave the outline, or ``h`` is not positive.
    """
    if element not in ("tri3", "tri6", "quad4"):
        raise MeshError(f"domain() makes tri3, tri6 or quad4 meshes, not {element!r}")
    if not h > 0:
        raise MeshError(f"the element size h must be positive, got {h}")
    named = dict(inclusions) if isinstance(inclusions, dict) else {
        f"inclusion{k + 1}": s for k, s in enumerate(inclusions)}
    shapes = [outline, *holes, *named.values()]
    size = 2 * h if element == "quad4" else h
    nodes, tri, regions, loops = _triangulate(shapes, _sample_loops(shapes, size), size, len(holes))
    mesh = Mesh(nodes, tri, "tri3", regions, {k + 1: n for k, n in enumerate(named)})
    if element != "tri3":
        mesh = _curved_quadratic(mesh, shapes, loops)
    if element == "quad4":
        mesh = _split_to_quads(mesh)
    check_orientation(mesh)
    return mesh


def _sample_loops(shapes, h):
    """Nodes on every curve, ``[(m_i, 2)]``, spaced ``min(h, turn * radius, gap, shape width)``,
    then no more than the size that the other curves' nodes ask for nearby (see
    :func:`_size_field`), growing by at most ``_GRADING`` per unit length along the curve."""
    dense = [shape._pieces(h) for shape in shapes]
    pts = [np.concatenate([p for p, _ in d]) for d in dense]
    _check_layout(shapes, pts)
    sizes = []
    for i, (shape, pieces) in enumerate(zip(shapes, dense)):
        others = [q for j, q in enumerate(pts) if j != i]
        gap = cKDTree(np.concatenate(others)).query(pts[i], distance_upper_bound=h)[0] if others else np.inf
        rho = np.concatenate([r for _, r in pieces])
        sizes.append(np.minimum(np.minimum(h, _TURN * rho), np.minimum(gap, shape._max_size)))
    first = [_place(shape, pieces, size) for shape, pieces, size in zip(shapes, dense, sizes)]
    loops = []
    for i, (shape, pieces, size) in enumerate(zip(shapes, dense, sizes)):
        others = [lp for j, lp in enumerate(first) if j != i]
        if others:
            size = np.minimum(size, _size_field(others, h)(pts[i]))
        loops.append(_place(shape, pieces, size))
    if sum(map(len, loops)) > 2_000_000:
        raise MeshError("more than 2 million curve nodes: increase h or separate the shapes")
    return loops


def _place(shape, pieces, size):
    """Nodes ``(m, 2)`` on the curve given by dense ``pieces``, about ``size`` apart (``size`` at
    the dense points, first limited to grow by ``_GRADING`` per unit length along the curve)."""
    p = np.concatenate([q for q, _ in pieces])
    arc = np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])
    a2, s2 = np.concatenate([arc, arc + arc[-1]]), np.concatenate([size, size])  # closed loop
    s2 = np.minimum(np.minimum.accumulate(s2 - _GRADING * a2) + _GRADING * a2,
                    np.minimum.accumulate((s2 + _GRADING * a2)[::-1])[::-1] - _GRADING * a2)
    size = np.minimum(s2[: len(p)], s2[len(p):])
    out, start = [], 0
    for q, _ in pieces:  # each piece starts with a node: polygon corners stay corners
        a, s = arc[start:start + len(q)] - arc[start], size[start:start + len(q)]
        count = np.concatenate([[0], np.cumsum(np.diff(a) * 0.5 * (1 / s[1:] + 1 / s[:-1]))])
        at = np.interp(np.linspace(0, count[-1], max(1, int(np.ceil(count[-1] - 1e-6))) + 1)[:-1], count, a)
        out.append(np.stack([np.interp(at, a, q[:, 0]), np.interp(at, a, q[:, 1])], -1))
        start += len(q)
    return shape.to_curve(np.concatenate(out))


def _check_layout(shapes, pts):
    for i in range(1, len(shapes)):
        if not shapes[0].contains(pts[i]).all():
            raise MeshError(f"{shapes[i]} is not strictly inside the outline {shapes[0]}")
        for j in range(1, len(shapes)):
            if j != i and shapes[j].contains(pts[i]).any():
                raise MeshError(f"{shapes[i]} and {shapes[j]} overlap; holes and inclusions must be disjoint")
    tol = 1e-9 * np.ptp(pts[0], 0).max()
    for i in range(len(shapes) - 1):
        near = cKDTree(pts[i]).query(np.concatenate(pts[i + 1:]), distance_upper_bound=tol)[0]
        if np.isfinite(near).any():
            raise MeshError(f"{shapes[i]} touches another curve; leave a gap between them")


def _spacing(loops):
    """Curve nodes ``(m, 2)`` and the longer of the two segments at each, ``(m,)``."""
    seg = [np.linalg.norm(lp - np.roll(lp, 1, 0), axis=1) for lp in loops]
    return np.concatenate(loops), np.concatenate([np.maximum(s, np.roll(s, -1)) for s in seg])


def _size_field(loops, h):
    """Target element size ``x (n, 2) -> (n,)``: ``min(h, s_j + grading * |x - p_j|)`` over the
    curve nodes ``p_j`` with spacing ``s_j`` (the nearest few stand for all)."""
    curve, spacing = _spacing(loops)
    tree = cKDTree(curve)

    def size(x):
        d, k = tree.query(x, k=min(8, len(curve)))
        return np.minimum(h, (spacing[k] + _GRADING * d).min(1))

    return size


def _interior_points(loops, h, inside):
    """Graded lattice points ``(n, 2)`` inside the domain, kept well away from the curve nodes:
    level ``k`` is an equilateral lattice of spacing ``h / 2^k``, used where the size is nearest."""
    curve, spacing = _spacing(loops)
    tree, size = cKDTree(curve), _size_field(loops, h)
    lo, hi = curve.min(0), curve.max(0)
    out = []
    for level in range(int(np.clip(np.round(np.log2(h / spacing.min())), 0, 30)) + 1):
        d, dy = h / 2**level, h / 2**level * np.sqrt(3) / 2
        if level == 0:
            ij = [np.arange(-1, (hi - lo)[0] / d + 2), np.arange(-1, (hi - lo)[1] / dy + 2)]
            ij = np.stack([a.ravel() for a in np.meshgrid(*ij)], -1)
        else:  # only around the curve nodes that ask for this size
            near = spacing < np.sqrt(2) * d
            r = ((np.sqrt(2) * d - spacing[near]) / _GRADING)[:, None]
            c0 = np.floor((curve[near] - r - lo) / [d, dy]).astype(int) - 1
            c1 = np.ceil((curve[near] + r - lo) / [d, dy]).astype(int) + 1
            ij = np.unique(np.concatenate([np.stack([a.ravel() for a in np.meshgrid(
                np.arange(a0, b0), np.arange(a1, b1))], -1) for (a0, a1), (b0, b1) in zip(c0, c1)]), axis=0)
        x = lo + np.stack([(ij[:, 0] + 0.5 * (ij[:, 1] % 2)) * d, ij[:, 1] * dy], -1)  # brick rows
        x = x[inside(x)]
        s = size(x)
        x, s = x[np.round(np.log2(h / s)) == level], s[np.round(np.log2(h / s)) == level]
        dist, k = tree.query(x)
        out.append(x[dist >= _KEEP_OFF * np.maximum(s, spacing[k])])
    return np.concatenate(out)


def _triangulate(shapes, loops, h, n_holes):
    """Conforming Delaunay triangulation alternated with spring smoothing: nodes ``(n, 2)`` (curve
    nodes first, loop after loop), triangles ``(t, 3)`` counter-clockwise, region tags ``(t,)``,
    and the final curve loops."""

    inside = partial(_in_domain, shapes, n_holes)  # points tested keep off the curves: exact shapes
    free = _interior_points(loops, h, inside)
    for rnd in range(_ROUNDS):
        loops, free, tri, segs = _conform(shapes, loops, free)
        fixed = np.concatenate(loops)
        nodes = np.concatenate([fixed, free])
        tag = _classify(nodes, tri, segs, shapes, n_holes)
        tri, tag = tri[tag >= 0], tag[tag >= 0]
        if rnd == _ROUNDS - 1 or not len(free):
            break
        moved = _springs(nodes, tri, len(fixed), _size_field(loops, h))[len(fixed):]
        mid, half = nodes[segs].mean(1), 0.5 * np.linalg.norm(nodes[segs[:, 1]] - nodes[segs[:, 0]], axis=1)
        d, k = cKDTree(mid).query(moved, k=4)
        ok = inside(moved) & (d > 1.05 * half[k]).all(1)  # outside every segment's diametral circle
        free = np.where(ok[:, None], moved, free)
    used = np.zeros(len(nodes), bool)
    used[tri] = True
    return nodes[used], (np.cumsum(used) - 1)[tri], tag, loops


def _in_domain(shapes, n_holes, x):
    """Whether points ``(n, 2)`` are inside the outline ``shapes[0]`` and outside every hole."""
    return shapes[0].contains(x) & ~np.any([s.contains(x) for s in shapes[1:1 + n_holes]], axis=0)


def _conform(shapes, loops, free):
    """Delaunay triangles ``(t, 3)`` (counter-clockwise) of the curve and free nodes in which every
    curve segment is an edge: free nodes inside the diametral circle of a missing segment are
    dropped, a segment with none there is split at its point on the curve."""
    for _ in range(100):
        off = np.cumsum([0] + [len(lp) for lp in loops])
        segs = np.concatenate([o + np.stack([np.arange(len(lp)), np.roll(np.arange(len(lp)), -1)], -1)
                               for o, lp in zip(off, loops)])
        nodes = np.concatenate(loops + [free])
        tri, n = Delaunay(nodes).simplices, len(nodes)
        edges = np.sort(tri[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), 1) @ [n, 1]
        missing = np.flatnonzero(~np.isin(np.sort(segs, 1) @ [n, 1], edges))
        if not missing.size:
            a, b, c = (nodes[tri[:, k]] for k in range(3))
            flip = (b - a)[:, 0] * (c - a)[:, 1] < (b - a)[:, 1] * (c - a)[:, 0]
            tri[flip] = tri[flip][:, [0, 2, 1]]
            return loops, free, tri, segs
        ends = nodes[segs[missing]]
        hits = cKDTree(free.reshape(-1, 2)).query_ball_point(
            ends.mean(1), 0.5 * np.linalg.norm(ends[:, 1] - ends[:, 0], axis=1))
        free = np.delete(free, [k for hit in hits for k in hit], axis=0)
        split = missing[[len(hit) == 0 for hit in hits]]
        for li, (shape, lp) in enumerate(zip(shapes, loops)):
            k = split[(split >= off[li]) & (split < off[li + 1])] - off[li]
            loops[li] = np.insert(lp, k + 1, shape.to_curve(0.5 * (lp[k] + np.roll(lp, -1, 0)[k])), axis=0)
    raise MeshError("could not make the mesh follow every curve; try a smaller h")


def _classify(nodes, tri, segs, shapes, n_holes):
    """Region tag of every triangle: -1 outside the domain or in a hole, 0 background, k in
    inclusion k. Curve segments cut the triangulation into pieces that each lie in one region; a
    majority vote of the centroids decides which, so no centroid near a curve can mislead it."""
    n, t = len(nodes), len(tri)
    key = np.sort(tri[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), 1) @ [n, 1]  # edge j of cell c at 3c + j
    order = np.argsort(key, kind="stable")
    pair = np.flatnonzero(key[order][1:] == key[order][:-1])
    pair = pair[~np.isin(key[order][pair], np.sort(segs, 1) @ [n, 1])]
    graph = coo_matrix((np.ones(len(pair)), (order[pair] // 3, order[pair + 1] // 3)), shape=(t, t))
    count, piece = connected_components(graph, directed=False)
    c, size = nodes[tri].mean(1), np.bincount(piece, minlength=count)

    def vote(mask):
        return (np.bincount(piece, mask, count) > 0.5 * size)[piece]

    tag = np.where(vote(_in_domain(shapes, n_holes, c)), 0, -1)
    for k, shape in enumerate(shapes[1 + n_holes:]):
        tag[vote(shape.contains(c)) & (tag == 0)] = k + 1
    return tag


def _springs(nodes, tri, n_fixed, size):
    """Nodes ``(n, 2)`` after a few steps of Persson & Strang's distmesh: every edge is a spring
    that only pushes, with a rest length 20 % above the local target size, so nodes spread evenly
    at the graded size; the first ``n_fixed`` (curve) nodes stay."""
    e = tri[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)  # an inner edge twice, once per triangle
    x = nodes.copy()
    s = size(0.5 * (x[e[:, 0]] + x[e[:, 1]]))
    for _ in range(_STEPS):
        v = x[e[:, 0]] - x[e[:, 1]]
        length = np.linalg.norm(v, axis=1)
        rest = 1.2 * s * np.sqrt((length**2).sum() / (s**2).sum())
        f = v * (np.maximum(rest - length, 0) / length)[:, None]
        push = [np.bincount(e[:, 0], f[:, k], len(x)) - np.bincount(e[:, 1], f[:, k], len(x))
                for k in range(2)]
        x[n_fixed:] += 0.1 * np.stack(push, -1)[n_fixed:]  # 0.2 per edge
    return x


def _curved_quadratic(mesh, shapes, loops):
    """``tri6`` copy of a ``tri3`` mesh whose mid-edge nodes on a curve lie on that curve."""
    quad, n = to_quadratic(mesh), mesh.n_nodes
    edges = np.sort(mesh.cells[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1) @ [n, 1]
    mids, order = quad.cells[:, 3:6].ravel(), np.argsort(edges)
    nodes, off = quad.nodes.copy(), 0
    for shape, lp in zip(shapes, loops):
        seg = off + np.stack([np.arange(len(lp)), np.roll(np.arange(len(lp)), -1)], -1)
        m = mids[order[np.searchsorted(edges, np.sort(seg, 1) @ [n, 1], sorter=order)]]
        nodes[m] = shape.to_curve(nodes[m])
        off += len(lp)
    return Mesh(nodes, quad.cells, "tri6", mesh.regions, dict(mesh.region_names))


def _split_to_quads(tri6: Mesh) -> Mesh:
    """Three ``quad4`` per ``tri6`` cell: vertex, mid-edge, centroid, mid-edge."""
    c, centre = tri6.cells, tri6.n_nodes + np.arange(tri6.n_cells)
    quads = np.concatenate([np.stack([c[:, v], c[:, m1], centre, c[:, m0]], -1)
                            for v, m1, m0 in ((0, 3, 5), (1, 4, 3), (2, 5, 4))])
    nodes = np.concatenate([tri6.nodes, tri6.nodes[c[:, :3]].mean(1)])
    return Mesh(nodes, quads, "quad4", np.tile(tri6.regions, 3), dict(tri6.region_names))


def curve_nodes(mesh: Mesh, shape, tol: float | None = None) -> np.ndarray:
    """Indices of the nodes on the boundary curve of ``shape``, ordered by angle about their mean
    (counter-clockwise along an ellipse or rectangle).

    Works for any 2D mesh, one from :func:`plate` or one read from a file. ``tol`` is the largest
    distance from the curve (length units), by default ``1e-8`` times the mesh extent.
    """
    tol = 1e-8 * float(np.ptp(mesh.nodes, 0).max()) if tol is None else tol
    on = np.flatnonzero(np.linalg.norm(shape.to_curve(mesh.nodes) - mesh.nodes, axis=1) <= tol)
    if not on.size:
        return on
    rel = mesh.nodes[on] - mesh.nodes[on].mean(0)
    return on[np.argsort(np.arctan2(rel[:, 1], rel[:, 0]))]


def min_angles(mesh: Mesh) -> np.ndarray:
    """Smallest corner angle of every 2D cell in degrees, ``(n_cells,)``."""
    v = mesh.nodes[mesh.cells[:, : mesh.el.corners]]
    a, b = np.roll(v, 1, axis=1) - v, np.roll(v, -1, axis=1) - v
    cos = (a * b).sum(-1) / (np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1))
    return np.degrees(np.arccos(np.clip(cos, -1, 1))).min(1)


# ====================================================================== morph
class Morph(eqx.Module):
    """Smooth map from shape parameters to node coordinates, made by :func:`morph`.

    ``morph(params)``, with ``params`` ``(n_shapes, 5)`` = ``(cx, cy, a, b, angle)`` per shape
    (``a, b`` the semi-axes of an ellipse or the half sides of a rectangle, angle in radians),
    returns the nodes ``(n_nodes, 2)``; ``morph(morph.params0)`` returns the reference nodes.
    """

    nodes0: np.ndarray  # (n_nodes, 2)
    params0: np.ndarray  # (n_shapes, 5)
    weights: np.ndarray  # (n_shapes, n_nodes): 1 on and inside a shape, 0 on other boundaries

    def __call__(self, params):
        return morph_nodes(self.nodes0, params, self.params0, self.weights)


def morph(mesh: Mesh, shapes, band: float | None = None) -> Morph:
    """Prepare a differentiable morph of ``mesh`` that moves the curves of ``shapes``.

    The nodes on (and inside) a shape move by the affine map that takes the reference shape onto
    the new one, so they stay exactly on the new ellipse or rectangle. Every other node moves by
    that map times ``w = 1 - smoothstep(d / (d + d_other))``, with ``d`` its distance to the shape
    and ``d_other`` to the nearest node of another boundary or region interface, which therefore
    stay put. With ``band`` (length units) ``w`` is also 0 farther than ``band`` from the shape.

    Args:
        mesh: a 2D mesh whose boundary or region interfaces contain the curves of ``shapes``.
        shapes: :class:`Ellipse` or :class:`Rect` instances, e.g. those given to :func:`plate`.
        band: optional reach of the morph (length units).
    """
    nodes = mesh.nodes
    features = np.union1d(mesh.boundary_nodes(), _interface_nodes(mesh))
    weights = []
    for shape in shapes:
        if not isinstance(shape, _Affine):
            raise MeshError(f"only Ellipse and Rect shapes can be morphed, not {type(shape).__name__}")
        on = curve_nodes(mesh, shape)
        if len(on) < 3:
            raise MeshError(f"no curve of the mesh follows {shape}; pass the shapes used to build it")
        other = np.setdiff1d(features, on)
        dense = np.concatenate([p for p, _ in shape._pieces(np.ptp(nodes, 0).max() / 1000)])
        d = cKDTree(dense).query(nodes)[0]
        d_other = cKDTree(nodes[other]).query(nodes)[0] if len(other) else np.full(len(nodes), np.inf)
        t = np.clip(d / np.maximum(d + d_other, 1e-300), 0, 1)
        if band is not None:
            t = np.maximum(t, np.clip(d / band, 0, 1))
        w = 1 - t * t * (3 - 2 * t)
        w[on], w[shape.contains(nodes)], w[other] = 1.0, 1.0, 0.0
        weights.append(w)
    return Morph(nodes, np.stack([s.params for s in shapes]), np.stack(weights))


def _interface_nodes(mesh: Mesh) -> np.ndarray:
    """Nodes shared by cells of different regions."""
    r = np.repeat(mesh.regions, mesh.cells.shape[1])
    lo, hi = np.full(mesh.n_nodes, r.max(initial=0)), np.full(mesh.n_nodes, r.min(initial=0))
    np.minimum.at(lo, mesh.cells.ravel(), r)
    np.maximum.at(hi, mesh.cells.ravel(), r)
    return np.flatnonzero(lo != hi)


@jax.jit
def morph_nodes(nodes0, params, params0, weights):
    """Morphed nodes ``(n_nodes, 2)``: pure JAX, differentiable in ``params``.

    Args:
        nodes0: reference nodes ``(n_nodes, 2)``.
        params: new shape parameters ``(n_shapes, 5)`` = ``(cx, cy, a, b, angle)``.
        params0: reference shape parameters ``(n_shapes, 5)``.
        weights: blend weights ``(n_shapes, n_nodes)`` (see :func:`morph`).
    """
    c0, A0 = _frame(jnp.asarray(params0), jnp)
    c1, A1 = _frame(jnp.asarray(params), jnp)
    (a, b), (c, d) = A0[:, 0].T, A0[:, 1].T
    inv = jnp.stack([jnp.stack([d, -b], -1), jnp.stack([-c, a], -1)], -2) / (a * d - b * c)[:, None, None]
    M = A1 @ inv  # (s, 2, 2): each reference shape onto the new one
    x = jnp.asarray(nodes0)
    d = jnp.einsum("sij,snj->sni", M, x[None] - c0[:, None]) + c1[:, None] - x[None]
    return x + jnp.einsum("sn,sni->ni", jnp.asarray(weights), d)


def check_morph(mesh: Mesh, nodes) -> float:
    """Smallest ratio of morphed to reference Jacobian over all cells and quadrature points.

    Raises:
        InvertedElementError: a cell inverts; the message says what fraction of the change is valid.
    """
    nodes = np.asarray(nodes, float)
    ratio = mesh.jacobian_dets(nodes) / mesh.jacobian_dets()
    bad = np.flatnonzero((ratio <= 0).any(1))
    if bad.size:
        u, lo, hi = nodes - mesh.nodes, 0.0, 1.0
        for _ in range(30):  # largest s with nodes0 + s u valid; the morph is linear in (c, a, b)
            s = 0.5 * (lo + hi)
            lo, hi = (s, hi) if (mesh.jacobian_dets(mesh.nodes + s * u) > 0).all() else (lo, s)
        worst = ratio.min(1).argmin()
        raise InvertedElementError(
            f"the morph inverts {bad.size} of {mesh.n_cells} cells (worst: cell {worst} near x = "
            f"{mesh.centroids()[worst].round(3).tolist()}); only about {lo:.0%} of this change keeps "
            f"every cell valid: scale the change of centre and axes by at most {0.9 * lo:.2f}, or keep "
            "the shape farther from other boundaries")
    return float(ratio.min())
