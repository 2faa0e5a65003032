"""Meshing a :class:`~examples.hand.body.Body`: a rectilinear grid through every box's faces, its
bricks kept where their centre lies in the body, six Kuhn tetrahedra per brick, then ``tet10``.

The grid lines of each axis are the faces of every volume and bone (faces closer than ``snap`` mm
merged at their mean, so that two nearly equal faces do not cut a thin slab through the whole
hand), subdivided so that no brick is longer than ``h``. A brick belongs to the body if its centre
lies in a volume, to a bone if its centre lies in the bone's box: the mesh follows every face
exactly up to that snapping. The Kuhn split (``jaxfem.box``) is conforming between bricks, and the
grid's per-axis map keeps every Jacobian positive.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from jaxfem.exceptions import MeshError
from jaxfem.mesh import Mesh, box, check_orientation, to_quadratic
from .body import Body


@dataclass(frozen=True, eq=False)
class Hand:
    """A meshed hand.

    Attributes:
        body: the :class:`Body` it was meshed from.
        mesh: the ``tet10`` mesh; region 0 is soft tissue, region ``k + 1`` bone ``k`` (named).
        bone_nodes: node indices of each bone's cells, ``{name: (n,)}``, sorted, disjoint.
        held_nodes: the nodes of the held cut through the forearm (``y = min`` of the held volume).
        skin_facets: boundary facets but the held cut, ``(n_skin, 6)`` (VTK ``triangle6`` order, outward).
        skin_cells: the cell under each skin facet, ``(n_skin,)``.
        marks: the skin node nearest to each of the body's marks, ``{name: node}``.
        h: the largest brick edge, mm.
    """

    body: Body
    mesh: Mesh
    bone_nodes: dict
    held_nodes: np.ndarray
    skin_facets: np.ndarray
    skin_cells: np.ndarray
    marks: dict
    h: float

    @property
    def bone_cells(self) -> np.ndarray:
        """Whether each cell is bone, ``(n_cells,)``."""
        return self.mesh.regions > 0

    def skin_normals(self) -> np.ndarray:
        """Outward unit normal of each skin facet in the reference state, ``(n_skin, 3)``."""
        X = self.mesh.nodes[self.skin_facets[:, :3]]
        n = np.cross(X[:, 1] - X[:, 0], X[:, 2] - X[:, 0])
        return n / np.linalg.norm(n, axis=1, keepdims=True)


def _lines(coords, h, snap, fine=()):
    """Grid lines of one axis through ``coords``: near ones merged, gaps split to at most ``h``, or
    to the ``h_fine`` of each ``(lo, hi, h_fine)`` in ``fine`` whose interval overlaps the gap (mm)."""
    c = np.unique(np.asarray(coords, float))
    groups = [[c[0]]]
    for v in c[1:]:
        (groups[-1].append(v) if v - groups[-1][0] < snap else groups.append([v]))
    keys = [float(np.mean(g)) for g in groups]
    out = [keys[0]]
    for a, b in zip(keys[:-1], keys[1:]):
        size = min([h] + [hf for lo, hi, hf in fine if lo < b and hi > a])
        out.extend(np.linspace(a, b, max(1, int(np.ceil((b - a) / size - 1e-9))) + 1)[1:])
    return np.asarray(out)


def hand_mesh(body: Body, h: float, snap: float = 2.5, fine=()) -> Hand:
    """Mesh ``body`` with ``tet10`` elements no longer than ``h`` (mm) along any axis; box faces
    closer than ``snap`` mm share one grid plane. ``fine``: local refinement, ``(axis, lo, hi,
    h_fine)`` rows (mm): along ``axis`` (0, 1, 2: x, y, z) the grid's gaps that overlap ``[lo, hi]``
    are split to at most ``h_fine`` (a slab through the whole grid: e.g. along a finger, beyond the
    palm, only that finger is refined; :func:`along`).

    Raises:
        MeshError: ``h`` or an ``h_fine`` not positive, an axis not 0-2; the volumes not connected; a
            bone that gets no brick, touches the skin or touches another bone at this ``h`` (make ``h``
            smaller).
    """
    if not h > 0:
        raise MeshError(f"the element size h must be positive (mm), got {h}")
    for row in fine:
        if len(row) != 4 or row[0] not in (0, 1, 2) or not row[3] > 0:
            raise MeshError(f"a refinement is (axis 0-2, lo, hi, h_fine > 0) in mm, got {row}")
    boxes = list(body.volumes.values()) + [b.box for b in body.bones]
    g = [_lines([v for bx in boxes for v in (bx.lo[a], bx.hi[a])], h, snap,
                [(lo, hi, hf) for ax, lo, hi, hf in fine if ax == a]) for a in range(3)]
    n = [len(x) - 1 for x in g]
    centre = [0.5 * (x[1:] + x[:-1]) for x in g]
    Z, Y, X = np.meshgrid(centre[2], centre[1], centre[0], indexing="ij")  # voxel order of jaxfem.box
    c = np.stack([X.ravel(), Y.ravel(), Z.ravel()], -1)
    inside = body.inside(c)
    bone = np.zeros(len(c), np.int64)
    for k, b in reversed(list(enumerate(body.bones))):
        bone[b.box.contains(c) & inside] = k + 1
    grid = box(0, 0, 0, n[0], n[1], n[2], n[0], n[1], n[2], "tet4")
    voxel = np.arange(grid.n_cells) % len(c)
    keep = inside[voxel]
    used, cells = np.unique(grid.cells[keep], return_inverse=True)
    ijk = np.rint(grid.nodes[used]).astype(np.int64)
    nodes = np.stack([g[a][ijk[:, a]] for a in range(3)], -1)
    names = {0: "soft tissue", **{k + 1: b.name for k, b in enumerate(body.bones)}}
    lin = Mesh(nodes, cells.reshape(-1, 4), "tet4", bone[voxel[keep]], names)
    check_orientation(lin)
    _check_connected(lin)
    mesh = to_quadratic(lin)
    return _named(body, mesh, float(max(np.diff(x).max() for x in g)))


def along(body: Body, names, h_fine: float, axis: int) -> tuple:
    """The refinement rows of :func:`hand_mesh` that split each named volume along ``axis`` (0, 1,
    2: x, y, z; a phalanx along its length: the thumb's x, a finger's y) to at most ``h_fine`` mm.

    Raises:
        MeshError: a name that is not a volume of ``body``.
    """
    unknown = sorted(set(names) - set(body.volumes))
    if unknown:
        raise MeshError(f"the body has no volume(s) {unknown}; its volumes are {sorted(body.volumes)}")
    return tuple((axis, float(body.volumes[n].lo[axis]), float(body.volumes[n].hi[axis]), float(h_fine))
                 for n in names)


def _check_connected(mesh: Mesh) -> None:
    c = mesh.cells
    rows, cols = np.repeat(c, 4, axis=1).ravel(), np.tile(c, (1, 4)).ravel()
    adj = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(mesh.n_nodes,) * 2)
    k, label = connected_components(adj, directed=False)
    if k > 1:
        raise MeshError(f"the body's volumes form {k} separate pieces (sizes {np.bincount(label).tolist()} nodes); "
                        "make the boxes share faces")


def _named(body: Body, mesh: Mesh, h: float) -> Hand:
    X = mesh.nodes
    f = mesh.facets()
    key = np.sort(f[:, :3], axis=1)
    _, inv, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    outer = np.flatnonzero(counts[inv.ravel()] == 1)
    held = body.volumes[body.held]
    tol = 1e-9 * np.ptp(X, axis=0).max()
    cut = np.all(np.abs(X[f[outer], 1] - held.lo[1]) <= tol, axis=1)
    skin, held_nodes = outer[~cut], np.flatnonzero(np.abs(X[:, 1] - held.lo[1]) <= tol)
    skin_facets, skin_cells = f[skin], skin // len(mesh.el.facets)
    skin_nodes = np.unique(skin_facets)
    bones = {}
    for k, b in enumerate(body.bones):
        nodes = np.unique(mesh.cells[mesh.regions == k + 1])
        if nodes.size == 0:
            raise MeshError(f"bone {b.name!r} gets no element at h = {h:g} mm; make h smaller than its thickness")
        if np.intersect1d(nodes, skin_nodes).size:
            raise MeshError(f"bone {b.name!r} reaches the skin at h = {h:g} mm (no soft tissue left between); "
                            "make h smaller or the bone thinner")
        for other, seen in bones.items():
            if np.intersect1d(nodes, seen).size:
                raise MeshError(f"bones {other!r} and {b.name!r} share nodes at h = {h:g} mm, so no joint is "
                                "left between them; make h smaller or the joint gap wider")
        bones[b.name] = nodes
    marks = {name: int(skin_nodes[np.argmin(np.linalg.norm(X[skin_nodes] - np.asarray(p), axis=1))])
             for name, p in body.marks.items()}
    return Hand(body, mesh, bones, held_nodes, skin_facets, skin_cells, marks, h)
