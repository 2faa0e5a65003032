"""Thin walls meshed by extrusion: a disc plate, optionally with an elliptic through-hole, and the
same plate with a rim standing on its outer ring (a wall with a raised edge).

The plate's outer face is the plane z = 0, its inner face z = ``thickness``; a rim rises on the
ring ``r_in < r < r_out`` to z = ``height``. The mesh is the extrusion of a 2D triangle mesh of the
disk of radius ``r_out`` (the *plan*): the inner disk ``r < r_in`` (minus the hole) is meshed by
:func:`jaxfem.domain` with edges following the hole, the ring ``r_in < r < r_out`` is a structured
polar grid through the inner disk's nodes on the circle ``r_in``, so both conform. Each triangle
becomes a prism per layer (inner disk: the plate's layers only; ring: every layer up to the rim),
each prism three tetrahedra split by global node order (conforming between neighbours), then
``tet10`` gets straight mid-edge nodes. The plan and the plan node under each vertex are kept, so
a morph of the plan moves the hole through the thickness (:mod:`refine.solid.morph`). No
dependency beyond numpy and scipy.

Lengths are in the caller's unit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .exceptions import MeshError
from .mesh import Mesh, fix_orientation, to_quadratic
from .mesher import domain
from .shapes import Ellipse, curve_nodes


@dataclass(frozen=True)
class ExtrudedWall:
    """An extruded wall mesh.

    Attributes:
        mesh: the 3D mesh (``tet4`` or ``tet10``, straight edges); regions by ``mesh.region_names``.
        plan: the ``tri3`` 2D mesh that was extruded (the hole's curve on its boundary; with a rim,
            region 1 under the rim, so a morph of the hole keeps the rim's feet).
        column: ``(n_vertices,)`` the plan node under each vertex of ``mesh`` (vertices first).
        facets: the boundary facets on the outer face z = 0, ``(n, 3 or 6)`` (where a load acts).
        hole: the hole's :class:`Ellipse` in the (x, y) plane, or ``None``.
    """

    mesh: Mesh
    plan: Mesh
    column: np.ndarray
    facets: np.ndarray
    hole: Ellipse | None = None


def _check(r_in, r_out, height, thickness, h, hole):
    if not (0 < r_in < r_out and 0 < thickness < height and h > 0):
        raise MeshError(f"a plate needs 0 < r_in < r_out and 0 < thickness < height and h > 0; got r_in={r_in}, "
                        f"r_out={r_out}, height={height}, thickness={thickness}, h={h}")
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


def rimmed_wall(r_in: float, r_out: float, thickness: float, height: float, h: float, hole: Ellipse | None = None,
                   element: str = "tet10", layers: int | None = None, hole_h: float | None = None,
                   floor_h: float | None = None, names: dict | None = None) -> ExtrudedWall:
    """Mesh a disc plate of radius ``r_out`` and ``thickness`` with a rim on its ring ``r_in < r <
    r_out`` up to z = ``height``, target element size ``h`` (length units), ``element``
    ``"tet10"`` (default) or ``"tet4"``; regions 0 (the plate inside the rim and under it, z <
    ``thickness``) and 1 (the rim above), named by ``names`` (default ``{0: "plate", 1: "rim"}``).

    ``hole``: an :class:`Ellipse` (centre, semi-axes, angle in the (x, y) plane) cut through the
    plate's whole thickness; it must lie inside the floor ``r < r_in`` with a gap of ``h / 4``.
    ``layers``: levels of elements through the plate (default ``thickness / h`` rounded, at least
    1). ``hole_h``: the largest element size (in plane) along the hole's curve (None: ``h``; the
    mesher also refines where the curve bends sharply), graded to ``h`` away from the hole
    (:func:`jaxfem.mesher.domain`'s ``curve_h``). ``floor_h``: the element size (in plane) inside
    ``r_in`` (None: ``h``; the ring keeps ``h`` radially).
    """
    if element not in ("tet4", "tet10"):
        raise MeshError(f"rimmed_wall() makes tet4 or tet10 meshes, not {element!r}")
    _check(r_in, r_out, height, thickness, h, hole)
    nodes2, tri, in_rim = _plan(r_in, r_out, h, hole, hole_h, floor_h)
    n_bot = layers or max(1, int(round(thickness / h)))
    n_rim = max(1, int(round((height - thickness) / h)))
    z = np.r_[np.linspace(0.0, thickness, n_bot + 1), np.linspace(thickness, height, n_rim + 1)[1:]]
    mesh, column = _extrude(nodes2, tri, z, lambda level: np.ones(len(tri), bool) if level < n_bot else in_rim,
                            lambda level: 0 if level < n_bot else 1, names or {0: "plate", 1: "rim"}, element)
    plan = fix_orientation(Mesh(nodes2, tri, "tri3", in_rim.astype(np.int64)))
    return ExtrudedWall(mesh, plan, column, outer_facets(mesh), hole)


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


def disc_wall(r_in: float, r_out: float, thickness: float, h: float, hole: Ellipse | None = None,
          element: str = "tet10", layers: int | None = None, hole_h: float | None = None,
          floor_h: float | None = None) -> ExtrudedWall:
    """Mesh the plate of :func:`rimmed_wall` with the same arguments, without the rim (the same
    plan, ``layers`` levels through the thickness, default ``thickness / h`` rounded, at most
    ``hole_h`` along the hole, ``floor_h`` inside ``r_in``), with the elliptic through-``hole`` if
    given; region 0 (``"plate"``). Lengths in the caller's unit."""
    if element not in ("tet4", "tet10"):
        raise MeshError(f"disc_wall() makes tet4 or tet10 meshes, not {element!r}")
    _check(r_in, r_out, 2 * thickness, thickness, h, hole)
    nodes2, tri, _ = _plan(r_in, r_out, h, hole, hole_h, floor_h)
    n = layers or max(1, int(round(thickness / h)))
    mesh, column = _extrude(nodes2, tri, np.linspace(0.0, thickness, n + 1), lambda level: np.ones(len(tri), bool),
                            lambda level: 0, {0: "plate"}, element)
    plan = fix_orientation(Mesh(nodes2, tri, "tri3"))
    return ExtrudedWall(mesh, plan, column, outer_facets(mesh), hole)


def outer_facets(mesh: Mesh) -> np.ndarray:
    """The boundary facets of ``mesh`` on the plane z = 0 (the plate's outer face), ``(n, 3 or 6)``."""
    f = mesh.boundary_facets()
    on = np.all(np.abs(mesh.nodes[f, 2]) <= 1e-9 * np.ptp(mesh.nodes[:, 2]), axis=1)
    return f[on]
