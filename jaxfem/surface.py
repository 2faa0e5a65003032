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


def snap_to_surface(mesh: Mesh, points, tol: float, names=None) -> np.ndarray:
    """``points (n, 3)`` measured on a body's surface, moved onto its faceted mesh surface and a
    hair inside (the nearest point of the nearest boundary facets' corner triangles, then 1e-6 of
    the mesh size inwards), so that a probe finds their cells: a point on a curved surface lies up
    to a chord's sagitta outside the mesh.

    Raises:
        MeshError: a point farther than ``tol`` (length unit) from the surface, named.
    """
    P = np.asarray(points, float).reshape(-1, 3)
    f = mesh.boundary_facets()[:, :3]
    A, B, C = (mesh.nodes[f[:, i]] for i in range(3))
    k = min(12, len(f))
    _, cand = cKDTree((A + B + C) / 3).query(P, k=k)
    cand = cand.reshape(len(P), k)
    best = np.full(len(P), np.inf)
    out = P.copy()
    for j in range(k):
        i = cand[:, j]
        q = _closest_on_triangle(P, A[i], B[i], C[i])
        d = np.linalg.norm(q - P, axis=1)
        take = d < best
        best[take], out[take] = d[take], q[take]
    far = np.flatnonzero(best > tol)
    if far.size:
        label = str(names[far[0]]) if names is not None else str(far[0])
        raise MeshError(f"{far.size} points are not on the model's surface (e.g. point {label}, "
                               f"{best[far[0]]:.3g} from it, more than {tol:.3g}); points must lie on the "
                               "body's surface: check the mesh's units and placement against the points")
    centre = mesh.nodes.mean(0)
    inward = centre - out
    inward /= np.maximum(np.linalg.norm(inward, axis=1, keepdims=True), 1e-300)
    return out + 1e-6 * np.ptp(mesh.nodes, 0).max() * inward


def _closest_on_triangle(P, A, B, C):
    """The nearest point of each triangle ``(A, B, C)`` to ``P``, all ``(n, 3)``: the plane's
    projection clamped into the triangle through a few barycentric fixes (exact enough for points
    within a facet or two of the surface)."""
    n = np.cross(B - A, C - A)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    Q = P - np.einsum("ni,ni->n", P - A, n)[:, None] * n
    for _ in range(3):
        v0, v1, v2 = B - A, C - A, Q - A
        d00, d01, d11 = (v0 * v0).sum(1), (v0 * v1).sum(1), (v1 * v1).sum(1)
        d20, d21 = (v2 * v0).sum(1), (v2 * v1).sum(1)
        den = d00 * d11 - d01 * d01
        v = np.clip((d11 * d20 - d01 * d21) / den, 0, 1)
        w = np.clip((d00 * d21 - d01 * d20) / den, 0, 1)
        s = v + w
        v, w = v / np.maximum(s, 1.0), w / np.maximum(s, 1.0)
        Q = A + v[:, None] * v0 + w[:, None] * v1
    return Q
