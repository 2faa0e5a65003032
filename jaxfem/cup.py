"""A parametric 3D cup holder: a short thick-walled cylinder with a bottom (the paper's Sec. 4 object),
optionally with a through-thickness elliptic hole in the bottom.

The axis is z; the bottom's outer face is the plane z = 0, the rim the plane z = ``height``. The
mesh is the extrusion of a 2D triangle mesh of the disk of radius ``r_out``: the inner disk
``r < r_in`` (minus the hole) is meshed by :func:`jaxfem.domain` with edges following the hole, the
annulus ``r_in < r < r_out`` is a structured polar grid through the inner disk's nodes on the circle
``r_in``, so both conform. Each triangle becomes a prism per layer (inner disk: the bottom's layers
only; annulus: every layer up to the rim), each prism three tetrahedra split by global node order
(conforming between neighbours), then ``tet10`` gets straight mid-edge nodes. No dependency beyond
numpy and scipy.

Lengths are in the caller's unit (mm in the examples).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .exceptions import MeshError
from .mesh import Mesh, fix_orientation, to_quadratic
from .mesher import domain
from .shapes import Ellipse, curve_nodes


@dataclass(frozen=True)
class CupHolder:
    """A meshed cup holder and its named node sets.

    Attributes:
        mesh: the 3D mesh (``tet4`` or ``tet10``); region 0 is the bottom (z < ``bottom``), 1 the wall
            (``region_names`` ``{0: "bottom", 1: "wall"}``).
        sets: node indices by name, each sorted: ``"rim"`` (z = height), ``"bottom_outer"`` (z = 0),
            ``"bottom_inner"`` (the floor inside, z = bottom, r <= r_in), ``"wall_inner"`` (r = r_in,
            z >= bottom), ``"wall_outer"`` (r = r_out), ``"hole"`` (the hole's wall; empty without one).
        bottom_outer_facets: the boundary facets on z = 0, ``(n, 3 or 6)`` (a pushed bottom's load).
        r_in, r_out, height, bottom: the dimensions (length units).
        hole: the hole's :class:`Ellipse` in the (x, y) plane, or ``None``.
        plan: the ``tri3`` 2D mesh that was extruded (region 1 under the wall, so a morph of the
            hole keeps the wall's feet); column: ``(n_vertices,)`` the plan node under each vertex.
    """

    mesh: Mesh
    sets: dict
    bottom_outer_facets: np.ndarray
    r_in: float
    r_out: float
    height: float
    bottom: float
    hole: Ellipse | None = None
    plan: Mesh | None = None
    column: np.ndarray | None = None


def _check(r_in, r_out, height, bottom, h, hole):
    if not (0 < r_in < r_out and 0 < bottom < height and h > 0):
        raise MeshError(f"a cup holder needs 0 < r_in < r_out and 0 < bottom < height and h > 0; got r_in={r_in}, "
                        f"r_out={r_out}, height={height}, bottom={bottom}, h={h}")
    if hole is not None:
        ring = np.linspace(0, 2 * np.pi, 721)[:-1]
        edge = hole.to_curve(np.stack([np.cos(ring), np.sin(ring)], -1) * 2 * r_out + [hole.cx, hole.cy])
        if np.hypot(edge[:, 0], edge[:, 1]).max() >= r_in - 0.25 * h:
            raise MeshError(f"the hole {hole} must lie inside the floor r < r_in = {r_in} with a gap of at least "
                            f"h/4 = {0.25 * h} to the inner wall; make it smaller or move it to the centre")


def _plan(r_in, r_out, h, hole, hole_h=None, floor_h=None):
    """The 2D mesh of the disk: nodes ``(n, 2)``, triangles ``(m, 3)`` and whether each is in the
    annulus ``(m,)``; elements of at most ``hole_h`` along the hole's curve (None: the floor's), of
    ``floor_h`` inside ``r_in`` (None: ``h``)."""
    for name, v in (("hole_h", hole_h), ("floor_h", floor_h)):
        if v is not None and not v > 0:
            raise MeshError(f"the element size {name} must be positive, got {v}")
    inner = domain(Ellipse(0.0, 0.0, r_in, r_in), floor_h or h, holes=() if hole is None else (hole,),
                   curve_h=None if hole is None else [hole_h])
    ring = curve_nodes(inner, Ellipse(0.0, 0.0, r_in, r_in))
    theta = np.arctan2(inner.nodes[ring, 1], inner.nodes[ring, 0])
    ring = ring[np.argsort(theta)]
    n_rad = max(1, int(round((r_out - r_in) / h)))
    k = len(ring)
    radii = np.linspace(r_in, r_out, n_rad + 1)[1:]
    ang = np.arctan2(inner.nodes[ring, 1], inner.nodes[ring, 0])
    outer = (radii[:, None, None] * np.stack([np.cos(ang), np.sin(ang)], -1)[None]).reshape(-1, 2)
    ids = np.vstack([ring[None], inner.n_nodes + np.arange(n_rad * k).reshape(n_rad, k)])  # (n_rad + 1, k)
    a, b = ids[:-1], np.roll(ids[:-1], -1, axis=1)
    c, d = ids[1:], np.roll(ids[1:], -1, axis=1)
    quads = np.stack([a, b, d, c], -1).reshape(-1, 4)
    tri = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    nodes = np.vstack([inner.nodes, outer])
    return nodes, np.vstack([inner.cells, tri]), np.r_[np.zeros(inner.n_cells, bool), np.ones(len(tri), bool)]


def _prisms_to_tets(tri, n2, layers):
    """Three tetrahedra per prism (triangle ``tri`` between levels ``layers`` and ``layers + 1``);
    node id = level * n2 + 2D id. With the triangle's ids sorted a < b < c, every quadrilateral face
    gets the diagonal from its higher bottom node to its lower top node: conforming."""
    t = np.sort(tri, axis=1)
    lo = layers[:, None] * n2 + t
    hi = lo + n2
    a, b, c = lo.T
    A, B, C = hi.T
    return np.concatenate([np.stack([a, b, c, A], -1), np.stack([b, c, A, B], -1), np.stack([c, A, B, C], -1)])


def cup_holder(r_in: float, r_out: float, height: float, bottom: float, h: float, hole: Ellipse | None = None,
               element: str = "tet10", layers: int | None = None, hole_h: float | None = None,
               floor_h: float | None = None) -> CupHolder:
    """Mesh a cup holder of inner/outer radius ``r_in``/``r_out``, total ``height`` and ``bottom``
    thickness, target element size ``h`` (all length units), ``element`` ``"tet10"`` (default; the
    locking-free choice for nearly incompressible foams) or ``"tet4"``.

    ``hole``: an :class:`Ellipse` (centre, semi-axes, angle in the (x, y) plane) cut through the
    bottom's whole thickness; it must lie inside the floor ``r < r_in``. ``layers``: levels of
    elements through the bottom (default ``bottom / h`` rounded, at least 1). ``hole_h``: the
    largest element size (in plane) along the hole's curve (None: ``h``; the mesher also refines
    where the curve bends sharply); the plan grades from it to ``h`` away from the hole
    (:func:`jaxfem.mesher.domain`'s ``curve_h``). ``floor_h``: the element size (in plane) of the
    floor inside ``r_in`` (None: ``h``; the annulus under the wall keeps ``h`` radially).
    """
    if element not in ("tet4", "tet10"):
        raise MeshError(f"cup_holder() makes tet4 or tet10 meshes, not {element!r}")
    _check(r_in, r_out, height, bottom, h, hole)
    nodes2, tri, in_wall = _plan(r_in, r_out, h, hole, hole_h, floor_h)
    n_bot = layers or max(1, int(round(bottom / h)))
    n_wall = max(1, int(round((height - bottom) / h)))
    z = np.r_[np.linspace(0.0, bottom, n_bot + 1), np.linspace(bottom, height, n_wall + 1)[1:]]
    mesh, column = _extrude(nodes2, tri, z, lambda level: np.ones(len(tri), bool) if level < n_bot else in_wall,
                            lambda level: 0 if level < n_bot else 1, {0: "bottom", 1: "wall"}, element)
    plan = fix_orientation(Mesh(nodes2, tri, "tri3", in_wall.astype(np.int64)))
    return CupHolder(mesh, _sets(mesh, r_in, r_out, height, bottom, hole), _bottom_facets(mesh),
                     float(r_in), float(r_out), float(height), float(bottom), hole, plan, column)


def _extrude(nodes2, tri, z, used_at, region_at, names, element):
    """The prisms over the triangles ``tri`` of the 2D nodes ``nodes2`` that ``used_at(level)``
    selects, between the levels ``z``, as tetrahedra of ``element``; also the 2D node under
    each vertex ``(n_vertices,)``."""
    n2 = len(nodes2)
    cells, region = [], []
    for level in range(len(z) - 1):
        use = used_at(level)
        tets = _prisms_to_tets(tri[use], n2, np.full(use.sum(), level))
        cells.append(tets)
        region.append(np.full(len(tets), region_at(level)))
    cells, region = np.concatenate(cells), np.concatenate(region)
    X = np.concatenate([np.c_[nodes2, np.full(n2, zk)] for zk in z])
    used, cells = np.unique(cells, return_inverse=True)
    mesh = fix_orientation(Mesh(X[used], cells.reshape(-1, 4), "tet4", region, names))
    return (to_quadratic(mesh) if element == "tet10" else mesh), used % n2


@dataclass(frozen=True)
class CupBottom:
    """The bottom slab of a cup holder (the disk ``r < r_out``, ``0 <= z <= bottom``): a paper's
    local model of the observed bottom.

    Attributes:
        mesh: the 3D mesh (``tet4`` or ``tet10``, straight edges), region 0.
        plan: the ``tri3`` 2D mesh that was extruded (its hole's curve on its boundary).
        column: ``(n_vertices,)`` the plan node under each vertex of ``mesh`` (vertices first).
        facets: the boundary facets on z = 0, ``(n, 3 or 6)``.
        hole: the hole's :class:`Ellipse` or ``None``.
    """

    mesh: Mesh
    plan: Mesh
    column: np.ndarray
    facets: np.ndarray
    hole: Ellipse | None = None


def cup_bottom(r_in: float, r_out: float, bottom: float, h: float, hole: Ellipse | None = None,
               element: str = "tet10", layers: int | None = None, hole_h: float | None = None,
               floor_h: float | None = None) -> CupBottom:
    """Mesh the bottom slab of the cup holder :func:`cup_holder` would mesh with the same
    arguments (the same plan, ``layers`` levels through the thickness, default ``bottom / h``
    rounded, at most ``hole_h`` along the hole, ``floor_h`` inside ``r_in``), with the elliptic
    through-``hole`` if given.
    Lengths in the caller's unit."""
    if element not in ("tet4", "tet10"):
        raise MeshError(f"cup_bottom() makes tet4 or tet10 meshes, not {element!r}")
    _check(r_in, r_out, 2 * bottom, bottom, h, hole)
    nodes2, tri, _ = _plan(r_in, r_out, h, hole, hole_h, floor_h)
    n = layers or max(1, int(round(bottom / h)))
    mesh, column = _extrude(nodes2, tri, np.linspace(0.0, bottom, n + 1), lambda level: np.ones(len(tri), bool),
                            lambda level: 0, {0: "bottom"}, element)
    plan = fix_orientation(Mesh(nodes2, tri, "tri3"))
    return CupBottom(mesh, plan, column, _bottom_facets(mesh), hole)


def _sets(mesh, r_in, r_out, height, bottom, hole):
    X = mesh.nodes
    r, z = np.hypot(X[:, 0], X[:, 1]), X[:, 2]
    tol = 1e-9 * max(r_out, height)
    # mid-edge nodes of tet10 lie on chords of the circles: a chord's sagitta is within h^2 / (8 r)
    sag = 1e-3 * r_out + tol
    sets = {
        "rim": np.flatnonzero(np.abs(z - height) <= tol),
        "bottom_outer": np.flatnonzero(np.abs(z) <= tol),
        "bottom_inner": np.flatnonzero((np.abs(z - bottom) <= tol) & (r <= r_in + tol)),
        "wall_inner": np.flatnonzero((r >= r_in - _sagitta(mesh, r_in) - tol) & (r <= r_in + tol) & (z >= bottom - tol)),
        "wall_outer": np.flatnonzero(r >= r_out - _sagitta(mesh, r_out) - sag),
        "hole": np.zeros(0, np.int64),
    }
    if hole is not None:
        # vertices lie on the curve, mid-edge nodes on chords inside it (the ellipse is convex)
        bnd = mesh.boundary_nodes()
        grown = Ellipse(hole.cx, hole.cy, hole.rx + tol, hole.ry + tol, hole.angle)
        sets["hole"] = bnd[grown.contains(X[bnd, :2]) & (z[bnd] <= bottom + tol)]
    return {k: np.sort(v) for k, v in sets.items()}


def _sagitta(mesh, radius):
    """How far inside a circle of ``radius`` a straight edge's midpoint may lie (the longest
    boundary edge's sagitta, length units)."""
    f = mesh.boundary_facets()[:, :3]
    e = np.linalg.norm(mesh.nodes[f[:, 0]] - mesh.nodes[f[:, 1]], axis=1).max()
    return e * e / (8 * radius)


def _bottom_facets(mesh):
    f = mesh.boundary_facets()
    on = np.all(np.abs(mesh.nodes[f, 2]) <= 1e-9 * np.ptp(mesh.nodes[:, 2]), axis=1)
    return f[on]
