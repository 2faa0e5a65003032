"""Values at scattered points on a 3D body's surface carried to the surface nodes near them: how a
3D model is driven by measured surface points (the 3D counterpart of
:func:`jaxfem.probe.boundary_interpolation`, which follows a 2D outline).

A surface node is driven when a point lies within ``radius`` of it and the node lies on the patch
its ``k`` nearest points sample (within ``radius / 4`` of their best-fit plane: a node on a
neighbouring face, off that plane, stays free); its value is a weighted least-squares affine fit
over those points in their plane (weights 1/d^2), exact for a field linear along the surface and
at a point that coincides with the node. So the patch of the surface seen by a camera is
prescribed and the unseen rest stays free.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from .exceptions import MeshError
from .mesh import Mesh


def _longest_boundary_edge(mesh: Mesh) -> float:
    f = mesh.boundary_facets()[:, :3]
    return float(np.linalg.norm(mesh.nodes[f] - mesh.nodes[np.roll(f, 1, axis=1)], axis=2).max())


def surface_interpolation(mesh: Mesh, points, radius: float, nodes=None, k: int = 6, tol: float | None = None,
                          names=None):
    """Linear map from values at surface points to the surface nodes near them.

    Args:
        mesh: a 3D mesh.
        points: ``(m, 3)`` positions on the surface (length units), m >= 3.
        radius: a surface node within this distance of a point is driven (length units).
        nodes: the driven nodes to use instead (e.g. those of all points, when some are lost in a
            frame); each gets its ``k`` nearest points whatever their distance.
        k: points fitted per node (at least 3 not on a line).
        tol: how far from every boundary node a point may lie (default: the longest boundary edge).
        names: labels of the points for error messages.

    Returns:
        ``(nodes (n,), W (n, m))`` with values at the nodes = ``W @ values``.

    Raises:
        MeshError: not a 3D mesh, fewer than 3 points, or points off the surface (named).
    """
    if mesh.dim != 3:
        raise MeshError("surface_interpolation() takes a 3D mesh; use boundary_interpolation() in 2D")
    pts = np.asarray(points, np.float64).reshape(-1, 3)
    if len(pts) < 3:
        raise MeshError(f"need at least three surface points to drive a 3D model, got {len(pts)}")
    bnd = mesh.boundary_nodes()
    tol = _longest_boundary_edge(mesh) if tol is None else tol
    dist, _ = cKDTree(mesh.nodes[bnd]).query(pts)
    far = np.flatnonzero(dist > tol)
    if far.size:
        labels = [str(names[i]) if names is not None else str(i) for i in far[:10]]
        raise MeshError(f"{far.size} surface points are not on the mesh surface (e.g. {', '.join(labels)}, "
                        f"{dist[far[0]]:.3g} from the nearest boundary node, more than {tol:.3g}); "
                        "boundary points must lie on the body's surface")
    tree = cKDTree(pts)
    kk = min(k, len(pts))
    fixed_nodes = nodes is not None
    nodes = bnd if nodes is None else np.asarray(nodes, np.int64)
    d, j = tree.query(mesh.nodes[nodes], k=kk)
    d, j = d.reshape(len(nodes), kk), j.reshape(len(nodes), kk)
    P = pts[j]  # (n, kk, 3)
    c = P.mean(1, keepdims=True)
    axes = np.linalg.svd(P - c)[2]  # (n, 3, 3): rows = in-plane directions, then the normal
    off = np.abs(np.einsum("ni,ni->n", mesh.nodes[nodes] - c[:, 0], axes[:, 2]))
    if not fixed_nodes:
        keep = (d[:, 0] <= radius) & (off <= 0.25 * radius)
        nodes, d, j, P, c, axes = nodes[keep], d[keep], j[keep], P[keep], c[keep], axes[keep]
    st = np.einsum("nki,nmi->nkm", P - c, axes[:, :2])  # in-plane coordinates of the points (n, kk, 2)
    A = np.concatenate([np.ones(st.shape[:2] + (1,)), st], -1)  # affine basis (n, kk, 3)
    w = 1.0 / np.maximum(d, 1e-9 * radius) ** 2
    e = np.concatenate([np.ones((len(nodes), 1)), np.einsum("ni,nmi->nm", mesh.nodes[nodes] - c[:, 0], axes[:, :2])], -1)
    AtW = np.swapaxes(A, 1, 2) * w[:, None, :]
    coef = np.einsum("ni,nij->nj", e, np.linalg.pinv(AtW @ A, rcond=1e-10) @ AtW)  # (n, kk)
    W = np.zeros((len(nodes), len(pts)))
    np.add.at(W, (np.repeat(np.arange(len(nodes)), kk), j.ravel()), coef.ravel())
    return nodes, W


#: flat triangles of a boundary face, by its type: local node triples (tri6: corners a, b, c, then
#: the mid-edge nodes of ab, bc, ca; a quadratic face is split at its mid-edge nodes into four)
FACE_TRIANGLES = {"tri3": [[0, 1, 2]], "tri6": [[0, 3, 5], [3, 1, 4], [5, 4, 2], [3, 4, 5]],
                  "quad4": [[0, 1, 2], [0, 2, 3]]}


def surface_triangles(mesh: Mesh, facets=None) -> np.ndarray:
    """A 3D mesh's boundary (or the boundary ``facets`` given, e.g. ``mesh.faces[name]``) as flat
    triangles ``(n, 3)`` of node indices (see :data:`FACE_TRIANGLES`)."""
    if mesh.dim != 3:
        raise MeshError("surface_triangles() takes a 3D mesh")
    local = FACE_TRIANGLES.get(mesh.el.facet)
    if local is None:
        raise MeshError(f"no triangles for a boundary face of type {mesh.el.facet!r}")
    facets = mesh.boundary_facets() if facets is None else np.asarray(facets)
    return np.ascontiguousarray(facets[:, np.asarray(local)].reshape(-1, 3))


def project_to_surface(mesh: Mesh, points, k: int = 16, facets=None):
    """The nearest point of a 3D mesh's surface to each point, and its distance.

    Each point is tested against the ``k`` surface triangles whose centroids are nearest to it
    (closest point on a triangle: its plane where the projection falls inside, else the nearest
    edge or corner).

    Args:
        mesh: a 3D mesh; points: ``(n, 3)``; k: candidate triangles per point; facets: the
            boundary facets to project onto (default: the whole surface).
    Returns:
        ``(foot (n, 3), distance (n,))``.
    """
    tri = surface_triangles(mesh, facets)
    P = np.asarray(points, np.float64).reshape(-1, 3)
    X = mesh.nodes[tri]  # (m, 3, 3)
    k = min(k, len(tri))
    _, cand = cKDTree(X.mean(axis=1)).query(P, k=k)
    cand = cand.reshape(len(P), k)
    foot = _closest_on_triangles(P[:, None, :], X[cand, 0], X[cand, 1], X[cand, 2])  # (n, k, 3)
    d = np.linalg.norm(foot - P[:, None, :], axis=2)
    best = np.argmin(d, axis=1)
    rows = np.arange(len(P))
    return foot[rows, best], d[rows, best]


def _closest_on_triangles(P, A, B, C):
    """Closest points of triangles ``(A, B, C)`` to ``P`` (broadcast shapes ``(..., 3)``): the
    projection onto the plane where it falls inside, else the nearest point of the three edges."""
    n = np.cross(B - A, C - A)
    nn = np.maximum(np.sum(n * n, axis=-1, keepdims=True), 1e-300)
    Q = P - np.sum((P - A) * n, axis=-1, keepdims=True) / nn * n  # projection onto the plane
    inside = np.ones(Q.shape[:-1], bool)
    for U, V in ((A, B), (B, C), (C, A)):
        inside &= np.sum(np.cross(V - U, Q - U) * n, axis=-1) >= 0
    best, dist = Q, np.where(inside, np.linalg.norm(P - Q, axis=-1), np.inf)
    for U, V in ((A, B), (B, C), (C, A)):
        UV = V - U
        t = np.clip(np.sum((P - U) * UV, axis=-1, keepdims=True) / np.maximum(np.sum(UV * UV, axis=-1, keepdims=True),
                                                                             1e-300), 0.0, 1.0)
        E = U + t * UV
        dE = np.linalg.norm(P - E, axis=-1)
        closer = ~inside & (dE < dist)
        best, dist = np.where(closer[..., None], E, best), np.where(closer, dE, dist)
    return best
