"""Meshes: nodes, cells of one element type, region tags, and structured generators.

A :class:`Mesh` is plain numpy data (it is built once, on the host). Region tags are integers per
cell (0 = background); a modulus per region and a modulus field are then the same per-cell array.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np

from .elements import Element, get_element
from .exceptions import InvertedElementError, MeshError


@dataclass(frozen=True, eq=False)
class Mesh:
    """An unstructured mesh of a single element type.

    Attributes:
        nodes: reference coordinates, ``(n_nodes, dim)`` float64, in the user's length unit.
        cells: node indices of each cell, ``(n_cells, n_per_cell)`` int64, counter-clockwise
            (positive Jacobian) ordering as in VTK/meshio.
        element: element name, see :mod:`jaxfem.elements`.
        regions: integer tag per cell, ``(n_cells,)``; 0 is the background.
        region_names: optional names of the tags, e.g. ``{1: "inclusion"}``.
        faces: named sets of boundary facets, ``{name: (k, nodes_per_facet) int64}`` in the order
            of :meth:`boundary_facets` (outward-oriented), e.g. a gmsh file's physical surfaces
            (:func:`jaxfem.read_mesh`); :meth:`side` and :meth:`side_facets` accept their names.
    """

    nodes: np.ndarray
    cells: np.ndarray
    element: str
    regions: np.ndarray | None = None
    region_names: dict = field(default_factory=dict)
    faces: dict = field(default_factory=dict)

    def __post_init__(self):
        nodes = np.ascontiguousarray(self.nodes, dtype=np.float64)
        cells = np.ascontiguousarray(self.cells, dtype=np.int64)
        el = get_element(self.element)
        if nodes.ndim != 2 or nodes.shape[1] not in (2, 3):
            raise MeshError(f"nodes must have shape (n_nodes, 2 or 3), got {nodes.shape}")
        if cells.ndim != 2 or cells.shape[1] != el.n_nodes:
            raise MeshError(f"{self.element} cells must have shape (n_cells, {el.n_nodes}), got {cells.shape}")
        if nodes.shape[1] != el.dim:
            raise MeshError(f"{self.element} is a {el.dim}D element but nodes are {nodes.shape[1]}D")
        if not np.all(np.isfinite(nodes)):
            bad = np.flatnonzero(~np.isfinite(nodes).all(1))
            raise MeshError(f"node coordinates contain NaN or inf (nodes {bad[:10].tolist()})")
        if cells.size and (cells.min() < 0 or cells.max() >= len(nodes)):
            raise MeshError(f"cells refer to node {cells.max()} but the mesh has {len(nodes)} nodes")
        regions = np.zeros(len(cells), np.int64) if self.regions is None else np.asarray(self.regions, np.int64)
        if regions.shape != (len(cells),):
            raise MeshError(f"regions must have shape ({len(cells)},), got {regions.shape}")
        object.__setattr__(self, "nodes", nodes)
        object.__setattr__(self, "cells", cells)
        object.__setattr__(self, "regions", regions)
        object.__setattr__(self, "faces", {str(n): _facet_array(f, n, el, len(nodes)) for n, f in self.faces.items()})

    # ------------------------------------------------------------------ basic properties
    @property
    def el(self) -> Element:
        return get_element(self.element)

    @property
    def dim(self) -> int:
        return self.nodes.shape[1]

    @property
    def n_nodes(self) -> int:
        return len(self.nodes)

    @property
    def n_cells(self) -> int:
        return len(self.cells)

    @property
    def n_dofs(self) -> int:
        return self.nodes.size

    def with_regions(self, regions: np.ndarray, names: dict | None = None) -> "Mesh":
        """The same mesh with new region tags."""
        return replace(self, regions=np.asarray(regions), region_names=dict(names or self.region_names))

    def with_faces(self, faces: dict) -> "Mesh":
        """The same mesh with further named faces ``{name: facets}`` (a name already there is replaced)."""
        return replace(self, faces={**self.faces, **faces})

    def with_nodes(self, nodes: np.ndarray) -> "Mesh":
        """The same topology on moved nodes (checked for inverted cells)."""
        m = replace(self, nodes=np.asarray(nodes))
        check_orientation(m)
        return m

    # ------------------------------------------------------------------ geometry
    def centroids(self) -> np.ndarray:
        """Cell centroids (mean of the vertex nodes), ``(n_cells, dim)``."""
        return self.nodes[self.cells[:, : self.el.corners]].mean(axis=1)

    def jacobian_dets(self, nodes: np.ndarray | None = None) -> np.ndarray:
        """Jacobian determinants at the quadrature points, ``(n_cells, n_qp)``."""
        X = self.nodes if nodes is None else nodes
        J = np.einsum("cni,qnj->cqij", X[self.cells], self.el.dN)
        return np.linalg.det(J)

    def volumes(self) -> np.ndarray:
        """Cell areas (2D) or volumes (3D), ``(n_cells,)``."""
        return (self.jacobian_dets() * self.el.weights).sum(axis=1)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return self.nodes.min(axis=0), self.nodes.max(axis=0)

    # ------------------------------------------------------------------ boundary
    def facets(self) -> np.ndarray:
        """All cell facets, ``(n_cells * n_facets_per_cell, nodes_per_facet)`` (with repeats)."""
        return self.cells[:, self.el.facets].reshape(-1, self.el.facets.shape[1])

    def boundary_facets(self) -> np.ndarray:
        """Facets that belong to exactly one cell, ``(n_bfacets, nodes_per_facet)``."""
        f = self.facets()
        key = np.sort(f[:, : get_element(self.el.facet).corners], axis=1)  # vertices identify a facet
        _, inv, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
        return f[counts[inv.ravel()] == 1]

    def boundary_nodes(self) -> np.ndarray:
        """Indices of the nodes on the boundary, sorted."""
        return np.unique(self.boundary_facets())

    def facets_with_corners(self, corners) -> tuple[np.ndarray, int]:
        """The boundary facets whose corner nodes are the rows of ``corners`` ``(k, n_corners)`` (in any
        order within a row), as rows of :meth:`boundary_facets` (the mesh's own node order), and how
        many rows match no boundary facet (e.g. facets inside the body)."""
        bf = self.boundary_facets()
        c = get_element(self.el.facet).corners
        index = {tuple(k): i for i, k in enumerate(np.sort(bf[:, :c], axis=1).tolist())}
        rows = [index.get(tuple(k)) for k in np.sort(np.asarray(corners)[:, :c], axis=1).tolist()]
        hit = [r for r in rows if r is not None]
        return bf[np.unique(np.asarray(hit, np.int64))], len(rows) - len(hit)

    def nodes_where(self, predicate: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
        """Indices of the nodes whose coordinates satisfy ``predicate(x) -> bool (n,)``."""
        return np.flatnonzero(predicate(self.nodes))

    def facets_where(self, predicate: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
        """Boundary facets all of whose nodes satisfy ``predicate``."""
        f = self.boundary_facets()
        ok = predicate(self.nodes[f.ravel()]).reshape(f.shape)
        return f[ok.all(axis=1)]

    def side(self, name: str, tol: float | None = None) -> np.ndarray:
        """Nodes of a named face (:attr:`faces`), sorted, or of a side of the bounding box: ``left``,
        ``right``, ``bottom``, ``top`` (and ``back``, ``front`` in 3D). A face the mesh names wins
        over the bounding-box side of the same name."""
        if name in self.faces:
            return np.unique(self.faces[name])
        return self.nodes_where(self._side_predicate(name, tol))

    def side_facets(self, name: str, tol: float | None = None) -> np.ndarray:
        """Boundary facets of a named face or on a side of the bounding box (see :meth:`side`)."""
        if name in self.faces:
            return self.faces[name]
        return self.facets_where(self._side_predicate(name, tol))

    def side_names(self) -> list[str]:
        """The names :meth:`side` takes: the named faces, then the bounding box's sides."""
        return list(dict.fromkeys([*self.faces, *BOX_SIDES[: 2 * self.dim]]))

    def _side_predicate(self, name, tol):
        lo, hi = self.bounds()
        tol = 1e-9 * float(np.max(hi - lo)) if tol is None else tol
        if name not in BOX_SIDES[: 2 * self.dim]:
            raise MeshError(f"unknown side {name!r} for a {self.dim}D mesh; it has {self.side_names()}"
                            + ("" if self.faces else " (no named faces: a gmsh file's physical groups of "
                               "boundary facets name them)"))
        ax = BOX_SIDES.index(name) // 2
        ref = lo if BOX_SIDES.index(name) % 2 == 0 else hi
        return lambda x: np.abs(x[:, ax] - ref[ax]) <= tol


#: the bounding box's sides, low then high along x, y, z
BOX_SIDES = ("left", "right", "bottom", "top", "back", "front")


def _facet_array(facets, name, el: Element, n_nodes: int) -> np.ndarray:
    """A named face's facets checked: ``(k, nodes_per_facet)`` node indices of the mesh."""
    f = np.asarray(facets)
    width = el.facets.shape[1]
    if f.ndim != 2 or f.shape[1] != width or not np.issubdtype(f.dtype, np.integer):
        raise MeshError(f"face {name!r} must be an integer array (k, {width}) of {el.facet} facets, got {f.shape}")
    if f.size and (f.min() < 0 or f.max() >= n_nodes):
        raise MeshError(f"face {name!r} refers to node {f.max()} but the mesh has {n_nodes} nodes")
    return np.ascontiguousarray(f, dtype=np.int64)


def check_orientation(mesh: Mesh, nodes: np.ndarray | None = None) -> None:
    """Raise :class:`InvertedElementError` if any cell has a non-positive Jacobian."""
    det = mesh.jacobian_dets(nodes)
    bad = np.flatnonzero((det <= 0).any(axis=1))
    if bad.size:
        raise InvertedElementError(
            f"{bad.size} of {mesh.n_cells} cells have a non-positive Jacobian (first: {bad[:8].tolist()}); "
            "reorder their nodes counter-clockwise (jaxfem.fix_orientation) or repair the mesh")


def fix_orientation(mesh: Mesh) -> Mesh:
    """Reverse the node order of clockwise linear cells (``tri3``/``tet4``) so every Jacobian is positive."""
    if mesh.element not in ("tri3", "tet4"):
        check_orientation(mesh)
        return mesh
    cells = mesh.cells.copy()
    neg = mesh.jacobian_dets()[:, 0] < 0
    cells[neg, 1], cells[neg, 2] = mesh.cells[neg, 2], mesh.cells[neg, 1]
    return replace(mesh, cells=cells)


# ====================================================================== generators
def rectangle(x0: float, y0: float, x1: float, y1: float, nx: int, ny: int,
              element: str = "tri3") -> Mesh:
    """Structured mesh of the rectangle ``[x0, x1] x [y0, y1]`` with ``nx x ny`` squares.

    ``tri3`` splits each square into two triangles with diagonals alternating in a chessboard
    pattern (no preferred direction); ``tri6`` adds mid-side nodes to that; ``quad4`` keeps them.
    """
    if nx < 1 or ny < 1:
        raise MeshError(f"need at least one cell each way, got nx={nx}, ny={ny}")
    xs, ys = np.linspace(x0, x1, nx + 1), np.linspace(y0, y1, ny + 1)
    X, Y = np.meshgrid(xs, ys, indexing="xy")
    nodes = np.stack([X.ravel(), Y.ravel()], -1)
    i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="xy")
    i, j = i.ravel(), j.ravel()
    n00 = j * (nx + 1) + i
    n10, n01, n11 = n00 + 1, n00 + nx + 1, n00 + nx + 2
    if element == "quad4":
        return Mesh(nodes, np.stack([n00, n10, n11, n01], -1), "quad4")
    if element not in ("tri3", "tri6"):
        raise MeshError(f"rectangle() makes tri3, tri6 or quad4 meshes, not {element!r}")
    flip = (i + j) % 2 == 1
    a = np.where(flip[:, None], np.stack([n00, n10, n01], -1), np.stack([n00, n10, n11], -1))
    b = np.where(flip[:, None], np.stack([n10, n11, n01], -1), np.stack([n00, n11, n01], -1))
    tri = np.empty((2 * len(n00), 3), np.int64)
    tri[0::2], tri[1::2] = a, b
    mesh = Mesh(nodes, tri, "tri3")
    return to_quadratic(mesh) if element == "tri6" else mesh


def box(x0: float, y0: float, z0: float, x1: float, y1: float, z1: float,
        nx: int, ny: int, nz: int, element: str = "hex8") -> Mesh:
    """Structured mesh of a box with ``nx x ny x nz`` bricks: ``hex8``, or ``tet4``/``tet10`` with six
    tetrahedra per brick (Kuhn split, conforming across bricks)."""
    g = [np.linspace(a, b, n + 1) for a, b, n in ((x0, x1, nx), (y0, y1, ny), (z0, z1, nz))]
    Z, Y, X = np.meshgrid(g[2], g[1], g[0], indexing="ij")
    nodes = np.stack([X.ravel(), Y.ravel(), Z.ravel()], -1)
    k, j, i = (a.ravel() for a in np.meshgrid(np.arange(nz), np.arange(ny), np.arange(nx), indexing="ij"))

    def nid(di, dj, dk):
        return ((k + dk) * (ny + 1) + (j + dj)) * (nx + 1) + (i + di)

    corners = [nid(0, 0, 0), nid(1, 0, 0), nid(1, 1, 0), nid(0, 1, 0),
               nid(0, 0, 1), nid(1, 0, 1), nid(1, 1, 1), nid(0, 1, 1)]
    if element == "hex8":
        return Mesh(nodes, np.stack(corners, -1), "hex8")
    if element not in ("tet4", "tet10"):
        raise MeshError(f"box() makes hex8, tet4 or tet10 meshes, not {element!r}")
    c = np.stack(corners, -1)
    # Kuhn: every tet runs from corner 0 to corner 6 along one monotone path of cube edges.
    paths = [(0, 1, 2, 6), (0, 1, 5, 6), (0, 3, 2, 6), (0, 3, 7, 6), (0, 4, 5, 6), (0, 4, 7, 6)]
    tets = np.concatenate([c[:, list(p)] for p in paths])
    mesh = fix_orientation(Mesh(nodes, tets, "tet4"))
    return to_quadratic(mesh) if element == "tet10" else mesh


_EDGES = {"tri3": ("tri6", [(0, 1), (1, 2), (2, 0)]),
          "tet4": ("tet10", [(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)])}


def to_quadratic(mesh: Mesh) -> Mesh:
    """Add straight mid-edge nodes: ``tri3 -> tri6``, ``tet4 -> tet10``; regions and named faces are kept."""
    if mesh.element not in _EDGES:
        raise MeshError(f"to_quadratic() takes tri3 or tet4 meshes, not {mesh.element!r}")
    name, edges = _EDGES[mesh.element]
    e = np.stack([mesh.cells[:, list(p)] for p in edges], 1)  # (c, ne, 2)
    key = np.sort(e.reshape(-1, 2), axis=1)
    uniq, inv = np.unique(key, axis=0, return_inverse=True)
    mid = 0.5 * (mesh.nodes[uniq[:, 0]] + mesh.nodes[uniq[:, 1]])
    new = mesh.n_nodes + inv.reshape(len(mesh.cells), len(edges))
    out = Mesh(np.vstack([mesh.nodes, mid]), np.hstack([mesh.cells, new]), name, mesh.regions,
               dict(mesh.region_names))
    return out.with_faces({n: out.facets_with_corners(f)[0] for n, f in mesh.faces.items()}) if mesh.faces else out
