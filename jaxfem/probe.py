"""Values of nodal fields at arbitrary points, and boundary values interpolated from sparse points.

- :class:`Probe` locates points in a mesh once (cell and shape-function weights) so that a nodal
  field is evaluated at them by a fixed linear map, differentiable and cheap inside ``jit``.
- :func:`project_to_boundary` places points on a 2D mesh's outer boundary (distance, arc length).
- :func:`boundary_interpolation` builds the linear map from displacements measured at a few
  points on a 2D boundary to every boundary node, linear in arc length between neighbouring
  points (how the paper's set P drives the model).
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np
from scipy.spatial import cKDTree

from . import _config  # noqa: F401
from ._small import inv
from .elements import get_element
from .exceptions import MeshError
from .mesh import Mesh


@dataclass(frozen=True, eq=False)
class Probe:
    """Evaluation of nodal fields at fixed reference points.

    Attributes:
        cells: cell containing each point, ``(n_points,)``.
        nodes: the nodes of that cell, ``(n_points, n_per_cell)``.
        weights: shape-function values at the point, ``(n_points, n_per_cell)``.
    """

    cells: np.ndarray
    nodes: np.ndarray
    weights: np.ndarray
    #: cells a point may move into under a morph: its own and those sharing a corner with it,
    #: ``(n_points, m)`` (padded with its own cell); ``None``: the point keeps its cell
    neighbours: np.ndarray | None = None
    #: every cell's nodes ``(n_cells, n_per_cell)``, to look the neighbours' nodes up
    mesh_cells: np.ndarray | None = None

    def __call__(self, field):
        """``field (n_nodes, ...)`` -> values at the points ``(n_points, ...)``."""
        return jnp.einsum("pk,pk...->p...", self.weights, jnp.asarray(field)[self.nodes])

    def moved(self, X, points):
        """The same probe after the mesh nodes moved to ``X (n_nodes, dim)`` (a geometry morph),
        for the same physical ``points``, its weights recomputed (differentiably). A point the morph
        carried out of its cell is found again in the neighbouring cell that now holds it (among the
        cells two corner-sharing steps from its own; the choice is piecewise constant, the weights smooth,
        and the interpolated field continuous across it), so it is interpolated, not extrapolated.
        Linear simplices: the barycentric coordinates. Quadratic triangles (whose morphed edges may
        bend): Newton on the isoparametric map from the barycentric coordinates of the corners, a
        fixed number of steps (quadratic convergence from there)."""
        dim, k = X.shape[1], self.nodes.shape[1]
        if k != dim + 1 and not (dim == 2 and k == 6):
            raise MeshError("Probe.moved() supports linear triangles and tetrahedra and quadratic triangles only")
        if self.neighbours is not None:
            return self._relocated(X, points)
        Xe = jnp.asarray(X)[self.nodes]  # (p, k, d)
        pts = jnp.asarray(points)
        T = jnp.swapaxes(Xe[:, 1:dim + 1] - Xe[:, :1], 1, 2)  # (p, d, d): the corners' affine map
        lam = solve_small(T, pts - Xe[:, 0])
        if k == dim + 1:
            w = jnp.concatenate([1.0 - lam.sum(axis=1, keepdims=True), lam], axis=1)
            return Probe(self.cells, self.nodes, w)
        xi = lam
        shape = get_element("tri6").shape
        grad = jax.vmap(jax.jacfwd(shape))  # (p, 6, 2)
        for _ in range(_TRI6_NEWTON):
            r = jnp.einsum("pk,pki->pi", shape(xi), Xe) - pts
            J = jnp.einsum("pki,pkj->pij", Xe, grad(xi))
            xi = xi - solve_small(J, r)
        return Probe(self.cells, self.nodes, shape(xi))

    def _relocated(self, X, points):
        """:meth:`moved` over every candidate cell of each point, keeping the one that holds it.
        The choice is piecewise constant, so it is made on the candidates' weights with the
        nodes' motion held (no derivatives through it), and the weights of the chosen cell alone
        are computed again, differentiably: a derivative then costs one cell a point, not one
        per candidate (a quadratic mesh's ~46 candidates made the derivatives of 3,000 points
        ~13 times the cost of their values)."""
        p, m = self.neighbours.shape
        cand = self.neighbours.reshape(-1)
        pts = jnp.repeat(jnp.asarray(points), m, axis=0)
        held = jax.lax.stop_gradient(X)
        trial = Probe(cand, self.mesh_cells[cand], np.zeros((p * m, self.nodes.shape[1]))).moved(held, pts)
        dim = X.shape[1]
        corners = trial.weights if self.nodes.shape[1] == dim + 1 else _corner_coordinates(trial.weights, dim)
        outside = jnp.maximum(0.0, -corners.min(axis=1)).reshape(p, m)
        pick = jnp.argmin(outside, axis=1)  # the first candidate (its own cell) wins ties
        cells = jnp.asarray(self.neighbours)[jnp.arange(p), pick]
        nodes = jnp.asarray(self.mesh_cells)[cells]
        return Probe(cells, nodes, np.zeros((p, self.nodes.shape[1]))).moved(X, points)


_TRI6_NEWTON = 4


def solve_small(A, b):
    """``x (p, d)`` with ``A[i] x[i] = b[i]`` for a batch of 2 x 2 or 3 x 3 systems ``A (p, d, d)``,
    ``b (p, d)``, by the closed-form inverse (:mod:`jaxfem._small`).

    Not ``jnp.linalg.solve``: on CPU a batched solve is LAPACK's getrf and trsm run by jaxlib's
    ``ParallelBatchMap`` on XLA's intra-op pool; where a program runs two such kernels at once
    and the pool has two threads (two cores), each kernel's thread waits for its batch's work,
    queued behind the other, and the process hangs for good (jaxlib 0.10; seen in a diagnosis of
    3,000 points, where a model's points are interpolated on a morphed mesh)."""
    return jnp.einsum("pij,pj->pi", inv(A), b)


def _corner_coordinates(w6, dim):
    """Barycentric coordinates of a point in a quadratic triangle from its six shape-function
    values: the corner coordinates l_i solve N_i = l_i (2 l_i - 1), N_(mid ij) = 4 l_i l_j; from
    the mid-side values, l_i = sqrt(N_ij N_ik / (4 N_jk)) breaks down at edges, so take
    l_i = N_i + (N_ij + N_ik) / 2 (exact: l_i (2 l_i - 1) + 2 l_i (l_j + l_k) = l_i)."""
    del dim
    return jnp.stack([w6[:, 0] + 0.5 * (w6[:, 3] + w6[:, 5]),
                      w6[:, 1] + 0.5 * (w6[:, 3] + w6[:, 4]),
                      w6[:, 2] + 0.5 * (w6[:, 4] + w6[:, 5])], axis=1)


def _corner_neighbours(mesh: Mesh, cells: np.ndarray, rings: int = 2) -> np.ndarray:
    """For each cell in ``cells``, itself then every cell within ``rings`` steps of cells sharing
    a corner (a morph moves nodes by up to about a cell before the fit remeshes), padded with
    itself to a common width: ``(len(cells), m)``."""
    corners = mesh.cells[:, :mesh.dim + 1]
    incidence = [[] for _ in range(mesh.n_nodes)]
    for c, row in enumerate(corners):
        for n in row:
            incidence[n].append(c)

    def around(c):
        near = {c}
        for _ in range(rings):
            near = {d for e in near for n in corners[e] for d in incidence[n]}
        return [c] + sorted(near - {c})

    memo: dict[int, list[int]] = {}
    rows = [memo[c] if c in memo else memo.setdefault(c, around(c)) for c in cells]
    m = max(len(r) for r in rows)
    return np.array([r + [r[0]] * (m - len(r)) for r in rows], dtype=np.int64)


def locate(mesh: Mesh, points, tol: float = 1e-6, names=None) -> Probe:
    """Find the cell and local coordinates of each point (reference configuration).

    Args:
        mesh: the mesh.
        points: ``(n_points, dim)`` coordinates.
        tol: how far outside every cell (in reference coordinates) a point may lie and still be
            taken as on the boundary.
        names: optional labels of the points (e.g. bundle ids) for the error message.
    Raises:
        MeshError: naming the points that lie outside the mesh.
    """
    pts = np.asarray(points, np.float64)
    el = mesh.el
    best_cell, best_xi, best_out = find_cells(mesh, pts)
    bad = np.flatnonzero(best_out > tol)
    if bad.size:
        labels = [str(names[i]) if names is not None else str(i) for i in bad[:10]]
        raise MeshError(f"{bad.size} points lie outside the mesh (e.g. {', '.join(labels)} at "
                        f"{pts[bad[0]].round(4).tolist()}); they cannot be compared with the model")
    N = el.shape(best_xi).reshape(len(pts), el.n_nodes)
    simplex = el.name.startswith(("tri", "tet")) and el.n_nodes in (mesh.dim + 1, 6)
    neighbours = _corner_neighbours(mesh, best_cell) if simplex else None
    return Probe(best_cell, mesh.cells[best_cell], N, neighbours, mesh.cells if simplex else None)


def find_cells(mesh: Mesh, points):
    """The cell nearest to holding each point, its reference coordinates there, and how far outside
    it the point lies in reference coordinates (0 inside): ``(cells (n,), xi (n, dim), out (n,))``.
    :func:`locate` without its check (a caller that places points lying outside first)."""
    pts = np.asarray(points, np.float64)
    tree = cKDTree(mesh.centroids())
    k = min(24, mesh.n_cells)
    _, cand = tree.query(pts, k=k)
    cand = cand.reshape(len(pts), k)
    best_cell = np.full(len(pts), -1)
    best_xi = np.zeros((len(pts), mesh.el.dim))
    best_out = np.full(len(pts), np.inf)
    for j in range(k):  # a handful of candidates per point, vectorised over points
        c = cand[:, j]
        xi, out = _inverse_map(mesh, c, pts)
        better = out < best_out
        best_cell[better], best_xi[better], best_out[better] = c[better], xi[better], out[better]
    far = np.flatnonzero(best_out > 1e-6)
    if far.size and mesh.n_cells > k:  # a graded mesh: a coarse cell's centroid lies beyond 24 fine ones
        sub = find_cells_among(mesh, pts[far], tree, min(8 * k, mesh.n_cells))
        better = sub[2] < best_out[far]
        for a, b in zip((best_cell, best_xi, best_out), sub):
            a[far[better]] = b[better]
    return best_cell, best_xi, best_out


def find_cells_among(mesh: Mesh, pts, tree, k: int):
    """:func:`find_cells` over the ``k`` cells of nearest centroids (``tree``: their KD-tree)."""
    _, cand = tree.query(pts, k=k)
    cand = cand.reshape(len(pts), k)
    best = np.full(len(pts), -1), np.zeros((len(pts), mesh.el.dim)), np.full(len(pts), np.inf)
    for j in range(k):
        xi, out = _inverse_map(mesh, cand[:, j], pts)
        better = out < best[2]
        best[0][better], best[1][better], best[2][better] = cand[better, j], xi[better], out[better]
    return best


def _inverse_map(mesh, c, pts):
    """Reference coordinates of ``pts`` in cells ``c`` by Newton, and how far outside they are."""
    el = mesh.el
    Xe = mesh.nodes[mesh.cells[c]]
    xi = np.full((len(pts), el.dim), 1.0 / 3.0 if el.name.startswith(("tri", "tet")) else 0.0)
    for _ in range(8):
        N, dN = el.shape(xi), el.shape_grad(xi)
        r = np.einsum("pk,pki->pi", N, Xe) - pts
        J = np.einsum("pki,pkj->pij", Xe, dN)
        xi = xi - np.linalg.solve(J, r[..., None])[..., 0]
    if el.name.startswith(("tri", "tet")):
        out = np.maximum(0.0, np.maximum(-xi.min(axis=1), xi.sum(axis=1) - 1.0))
    else:
        out = np.maximum(0.0, np.abs(xi).max(axis=1) - 1.0)
    return xi, out


def boundary_loop(mesh: Mesh) -> np.ndarray:
    """The outer boundary of a 2D mesh as an ordered, counter-clockwise loop of node indices
    (mid-edge nodes included for quadratic elements)."""
    if mesh.dim != 2:
        raise MeshError("boundary_loop() is for 2D meshes")
    f = mesh.boundary_facets()
    nxt = {}
    for e in f:
        chain = [e[0]] + list(e[2:]) + [e[1]]  # vertex, mid-side node(s), vertex
        for a, b in zip(chain[:-1], chain[1:]):
            nxt[a] = b
    loops, seen = [], set()
    for start in nxt:
        if start in seen:
            continue
        loop, n = [], start
        while n not in seen:
            seen.add(n)
            loop.append(n)
            n = nxt[n]
        loops.append(np.array(loop))

    def area(lp):
        x, y = mesh.nodes[lp, 0], mesh.nodes[lp, 1]
        return 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)

    outer = max(loops, key=lambda lp: abs(area(lp)))
    return outer if area(outer) > 0 else outer[::-1]


@dataclass(frozen=True, eq=False)
class BoundaryProjection:
    """Points projected onto the outer boundary of a 2D mesh (:func:`project_to_boundary`).

    Attributes:
        loop: the outer boundary's nodes, counter-clockwise, ``(n_b,)``.
        node_arc: arc length of each loop node from ``loop[0]``, ``(n_b,)``, length unit.
        perimeter: the loop's length.
        arc: arc length of each point's projection, ``(m,)``.
        distance: distance of each point from the boundary, ``(m,)``.
        foot: the projections, ``(m, 2)``.
    """

    loop: np.ndarray
    node_arc: np.ndarray
    perimeter: float
    arc: np.ndarray
    distance: np.ndarray
    foot: np.ndarray


def project_to_boundary(mesh: Mesh, points) -> BoundaryProjection:
    """Project ``points (m, 2)`` onto the nearest place of the outer boundary of a 2D ``mesh``."""
    loop = boundary_loop(mesh)
    P = mesh.nodes[loop]
    seg = np.roll(P, -1, axis=0) - P
    L = np.linalg.norm(seg, axis=1)
    s_nodes = np.concatenate([[0.0], np.cumsum(L)[:-1]])
    pts = np.asarray(points, np.float64).reshape(-1, 2)
    # project each point on every boundary segment, keep the nearest
    d = pts[:, None, :] - P[None]
    t = np.clip(np.einsum("msi,si->ms", d, seg) / (L**2)[None], 0.0, 1.0)
    proj = P[None] + t[..., None] * seg[None]
    dist = np.linalg.norm(pts[:, None] - proj, axis=2)
    j = dist.argmin(axis=1)
    rows = np.arange(len(pts))
    return BoundaryProjection(loop, s_nodes, float(L.sum()), s_nodes[j] + t[rows, j] * L[j], dist[rows, j],
                              proj[rows, j])


def boundary_interpolation(mesh: Mesh, points, tol: float | None = None, names=None):
    """Linear map from values at points on the outer boundary to every node of that boundary.

    Each point is placed at its projection on the boundary (within ``tol`` of it). Between
    neighbouring points (in order along the boundary) values vary linearly with arc length; the
    loop is closed, so the last point connects to the first. Points that project to the same
    place share it: their mean value holds there.

    Args:
        mesh: a 2D mesh.
        points: ``(m, 2)`` positions on the boundary (m >= 2).
        tol: how far from the boundary a point may be (default: 1 % of the mean boundary edge).
        names: labels for error messages.
    Returns:
        ``(nodes (n_b,), W (n_b, m))`` with values at the nodes = ``W @ values``.
    """
    pts = np.asarray(points, np.float64)
    if len(pts) < 2:
        raise MeshError("need at least two boundary points to interpolate along the boundary")
    pr = project_to_boundary(mesh, pts)
    loop, s_nodes, perimeter = pr.loop, pr.node_arc, pr.perimeter
    tol = 0.01 * perimeter / len(loop) if tol is None else tol
    far = np.flatnonzero(pr.distance > tol)
    if far.size:
        worst = far[np.argmax(pr.distance[far])]
        label = str(names[worst]) if names is not None else str(worst)
        raise MeshError(f"{far.size} boundary points are not on the mesh boundary (the farthest, {label}, is "
                        f"{pr.distance[worst]:.3g} away; allowed {tol:.3g}); boundary points must lie on the "
                        "domain's outline")
    # places along the boundary; points at the same place are averaged there
    order = np.argsort(pr.arc, kind="stable")
    sp = pr.arc[order]
    new = np.concatenate([[True], np.diff(sp) > 1e-12 * perimeter])
    if new.sum() < 2:
        raise MeshError("all boundary points project to the same place on the boundary")
    group = np.cumsum(new) - 1
    places = sp[new]
    A = np.zeros((len(places), len(pts)))  # values at places = A @ values at points
    A[group, order] = 1.0
    A /= A.sum(axis=1, keepdims=True)
    # periodic linear interpolation in arc length
    n = len(places)
    Wp = np.zeros((len(loop), n))
    ext = np.concatenate([places - perimeter, places, places + perimeter])
    idx = np.tile(np.arange(n), 3)
    k = np.searchsorted(ext, s_nodes, side="right") - 1
    a, b = ext[k], ext[k + 1]
    w = (s_nodes - a) / (b - a)
    rows = np.arange(len(loop))
    np.add.at(Wp, (rows, idx[k]), 1.0 - w)
    np.add.at(Wp, (rows, idx[k + 1]), w)
    return loop, Wp @ A
