"""Conforming triangle meshes of plates and domains with elliptic, rectangular or polygonal holes
and inclusions: element edges follow every curve, inclusions are tagged as regions.

:func:`plate` (or :func:`domain` for a polygon or elliptic outline) samples every curve with a
spacing set by the target size ``h``, the curvature and the gap to the nearest other curve, fills
the inside with a graded equilateral lattice, and builds a boundary-conforming Delaunay
triangulation (scipy) improved by a few distmesh-like spring steps. Curve nodes lie exactly on the
curves, so the area of a hole or an inclusion converges as O(h^2) with ``tri3``; ``tri6`` and
``quad4`` put their mid-edge nodes on the curves too (O(h^4) area error with ``tri6``).
"""

from __future__ import annotations

from functools import partial

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import Delaunay, cKDTree

from . import _config  # noqa: F401  (float64)
from .exceptions import MeshError
from .mesh import Mesh, check_orientation, to_quadratic
from .shapes import Rect

_TURN = np.pi / 6  # a chord turns by at most 30 degrees: >= 12 nodes on any circle of curvature
_GRADING = 0.3  # element size grows by at most this much per unit distance from a fine curve
_KEEP_OFF = 0.75  # lattice points closer than this many local sizes to a curve node are dropped
_ROUNDS, _STEPS = 3, 8  # rounds of Delaunay + spring smoothing, and spring steps per round


def plate(x0: float, y0: float, x1: float, y1: float, h: float, holes=(), inclusions=(),
          element: str = "tri3") -> Mesh:
    """Mesh of the rectangle ``[x0, x1] x [y0, y1]`` minus ``holes``, with ``inclusions`` tagged;
    see :func:`domain`."""
    return domain(Rect(x0, y0, x1, y1), h, holes, inclusions, element)


def domain(outline, h: float, holes=(), inclusions=(), element: str = "tri3", curve_h=None) -> Mesh:
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
        curve_h: the largest element size on each hole's and inclusion's curve, in the order
            ``holes`` then ``inclusions`` (length units; None, or an entry None: ``h``); the mesh
            grades from it to ``h`` away from the curve as it does from a sharply bent one.

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
    caps = [h, *(curve_h or [None] * (len(shapes) - 1))]
    if len(caps) != len(shapes) or not all(c is None or c > 0 for c in caps):
        raise MeshError(f"curve_h needs one positive size (or None) per hole and inclusion ({len(shapes) - 1}), "
                        f"got {curve_h}")
    caps = [size * min(1.0, (c or h) / h) for c in caps]
    nodes, tri, regions, loops = _triangulate(shapes, _sample_loops(shapes, size, caps), size, len(holes))
    mesh = Mesh(nodes, tri, "tri3", regions, {k + 1: n for k, n in enumerate(named)})
    if element != "tri3":
        mesh = _curved_quadratic(mesh, shapes, loops)
    if element == "quad4":
        mesh = _split_to_quads(mesh)
    check_orientation(mesh)
    return mesh


def _sample_loops(shapes, h, caps=None):
    """Nodes on every curve, ``[(m_i, 2)]``, spaced ``min(cap, turn * radius, gap, shape width)``
    (``caps``: one size per shape, each at most ``h``; None: ``h``),
    then no more than the size that the other curves' nodes ask for nearby (see
    :func:`_size_field`), growing by at most ``_GRADING`` per unit length along the curve."""
    dense = [shape._pieces(h) for shape in shapes]
    pts = [np.concatenate([p for p, _ in d]) for d in dense]
    _check_layout(shapes, pts)
    sizes, caps = [], caps or [h] * len(shapes)
    for i, (shape, pieces) in enumerate(zip(shapes, dense)):
        others = [q for j, q in enumerate(pts) if j != i]
        gap = cKDTree(np.concatenate(others)).query(pts[i], distance_upper_bound=h)[0] if others else np.inf
        rho = np.concatenate([r for _, r in pieces])
        sizes.append(np.minimum(np.minimum(caps[i], _TURN * rho), np.minimum(gap, shape._max_size)))
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
        e1, e2 = nodes[tri[:, 1]] - nodes[tri[:, 0]], nodes[tri[:, 2]] - nodes[tri[:, 0]]
        tag[e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0] <= 1e-9 * h * h] = -1  # flat: collinear nodes on the hull
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
