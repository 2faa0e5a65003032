"""Distances between a deformed model and an unlabelled cloud: point-to-boundary distances (JAX,
differentiable in the model's node positions), inside tests, a soft minimum, and the split of a
cloud into outline points and surface samples (SciPy's KD-tree, from the data alone).

The model's boundary is a set of facets: in 2D the chain of its boundary edges (segments, node
pairs), in 3D its boundary faces as flat triangles (node triples; a quadratic face is split at
its mid-edge nodes into four, so the triangles follow the deformed quadratic surface).
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
from scipy.spatial import cKDTree

import jaxfem as jf
from jaxfem.surface import surface_triangles

from refine.exceptions import CorrespondenceError


def boundary_facets(mesh: jf.Mesh) -> np.ndarray:
    """The model's boundary as flat facets: ``(n, 2)`` node pairs in 2D (outer outline and holes,
    corner nodes, each oriented with the material on its left, so that the outward normal of
    ``a -> b`` is ``(dy, -dx)``), ``(n, 3)`` node triples in 3D (boundary faces split into flat
    triangles at their mid-edge nodes, in the face's own order)."""
    if mesh.dim == 2:
        return np.ascontiguousarray(mesh.boundary_facets()[:, :2])
    try:
        return surface_triangles(mesh)
    except jf.MeshError as e:
        raise CorrespondenceError(f"{e}; use tet4, tet10 or hex8 meshes") from None


def segment_distances(P, A, B):
    """Distances from every point to every segment, ``(n_points, n_segments)``.

    Args:
        P: ``(n, dim)`` points; A, B: ``(m, dim)`` segment ends. Any dimension. Differentiable in
            all three (the clamp of the projection to the segment makes it piecewise smooth).
    """
    return point_segment_distance(P[:, None], A[None], B[None])


def point_segment_distance(P, A, B):
    """Distance from a point to a segment, broadcast over leading axes: ``P, A, B (..., dim)`` ->
    ``(...)`` (length). Differentiable in all three (piecewise smooth)."""
    AB = B - A
    t = jnp.sum((P - A) * AB, axis=-1) / jnp.maximum(jnp.sum(AB * AB, axis=-1), 1e-30)
    closest = A + jnp.clip(t, 0.0, 1.0)[..., None] * AB
    return jnp.sqrt(jnp.sum((P - closest) ** 2, axis=-1) + 1e-18)


def triangle_distances(P, A, B, C):
    """Distances from every point to every triangle, ``(n_points, n_triangles)``.

    Args:
        P: ``(n, 3)`` points; A, B, C: ``(m, 3)`` the triangles' corners. A point whose projection
            falls inside a triangle is at its distance to the plane, any other at its distance to
            the nearest edge. Differentiable in all four (piecewise smooth).
    """
    return point_triangle_distance(P[:, None], A[None], B[None], C[None])


def point_triangle_distance(P, A, B, C):
    """Distance from a point to a triangle, broadcast over leading axes: ``P, A, B, C (..., 3)`` ->
    ``(...)`` (length); as :func:`triangle_distances`."""
    n = jnp.cross(B - A, C - A)
    nn = jnp.maximum(jnp.sum(n * n, axis=-1), 1e-30)
    d = P - A
    # barycentric coordinates of the projection: signs of the sub-triangles' normals along n
    s_c = jnp.sum(jnp.cross(B - A, d) * n, axis=-1) / nn
    s_a = jnp.sum(jnp.cross(C - B, P - B) * n, axis=-1) / nn
    s_b = 1.0 - s_a - s_c
    within = (s_a >= 0) & (s_b >= 0) & (s_c >= 0)
    plane = jnp.sum(d * n, axis=-1) / jnp.sqrt(nn)
    edges = jnp.minimum(jnp.minimum(point_segment_distance(P, A, B), point_segment_distance(P, B, C)),
                        point_segment_distance(P, C, A))
    return jnp.where(within, jnp.sqrt(plane * plane + 1e-18), edges)


def facet_distances(P, x, facets):
    """Distances ``(n_points, n_facets)`` from points ``P (n, dim)`` to the facets ``(m, 2 or 3)``
    (node indices: segments in 2D, triangles in 3D) of node positions ``x (n_nodes, dim)``."""
    if facets.shape[1] == 2:
        return segment_distances(P, x[facets[:, 0]], x[facets[:, 1]])
    return triangle_distances(P, x[facets[:, 0]], x[facets[:, 1]], x[facets[:, 2]])


def candidate_distances(P, x, facets, candidates):
    """Distances ``(n_points, k)`` from points ``P (n, dim)`` to their own ``k`` candidate facets
    ``candidates (n, k)`` (indices into ``facets``, :func:`shortlist`) at node positions ``x``:
    :func:`facet_distances` on a shortlist, so that a point costs k facets, not all of them."""
    F = facets[candidates]  # (n, k, 2 or 3) node indices
    Q = P[:, None, :]
    if facets.shape[1] == 2:
        return point_segment_distance(Q, x[F[..., 0]], x[F[..., 1]])
    return point_triangle_distance(Q, x[F[..., 0]], x[F[..., 1]], x[F[..., 2]])


def shortlist(points: np.ndarray, x: np.ndarray, facets: np.ndarray, k: int) -> np.ndarray:
    """The ``k`` facets whose centroids lie nearest each point (SciPy's KD-tree): ``(n, k)``
    indices into ``facets``, at node positions ``x (n_nodes, dim)``. The nearest facet is among
    them while the facets are small beside the distance the model moves before the list is made
    again (:meth:`refine.correspond.fit.Fitter.fit` checks it)."""
    centroids = np.asarray(x, float)[np.asarray(facets)].mean(axis=1)
    k = min(int(k), len(facets))
    _, idx = cKDTree(centroids).query(np.asarray(points, float), k)
    return np.asarray(idx, np.int64).reshape(len(points), k)


def softmin(D, tau: float, axis: int = -1):
    """A smooth minimum ``-tau log sum exp(-D / tau)`` along ``axis`` (a little below the minimum,
    by at most ``tau log m``); its gradient spreads over the near-minimal entries."""
    m = jnp.min(D, axis=axis, keepdims=True)
    return jnp.squeeze(m, axis) - tau * jnp.log(jnp.sum(jnp.exp(-(D - m) / tau), axis=axis))


def inside(P, A, B):
    """``(n,)`` True for 2D points inside the region bounded by the segments (crossing number of a
    ray in +x); holes are outside. Not differentiable (a mask)."""
    ya, yb = A[None, :, 1], B[None, :, 1]
    y = P[:, None, 1]
    straddle = (ya > y) != (yb > y)
    x_cross = A[None, :, 0] + (y - ya) * (B[None, :, 0] - A[None, :, 0]) / jnp.where(straddle, yb - ya, 1.0)
    crossings = jnp.sum(straddle & (x_cross > P[:, None, 0]), axis=1)
    return crossings % 2 == 1


def split_outline(cloud: np.ndarray, tol: float, k: int = 10, share: float = 0.7) -> np.ndarray:
    """Which points of a 2D cloud lie on its outline: ``(n,)`` bool.

    The outline is sampled densely along a curve, the surface sparsely. A point is on the outline
    when a line through it and one of its ``k`` nearest neighbours passes within ``tol`` (length,
    a few noise levels) of at least ``share`` of those neighbours: a consensus of lines through
    the point (RANSAC-like), so that a surface sample among the neighbours does not tilt it, and a
    surface sample just inside the outline (whose neighbours lie on a line beside it) fails.
    From the data alone, before any model.
    """
    cloud = np.asarray(cloud, float)
    n = len(cloud)
    if n < k + 1:
        return np.ones(n, bool)
    _, idx = cKDTree(cloud).query(cloud, k + 1)
    d = cloud[idx[:, 1:]] - cloud[:, None]  # (n, k, 2): the neighbours seen from the point
    u = d / np.maximum(np.linalg.norm(d, axis=2, keepdims=True), 1e-300)
    off = np.abs(d[:, :, None, 0] * u[:, None, :, 1] - d[:, :, None, 1] * u[:, None, :, 0])  # (n, i, j)
    inliers = (off < tol).sum(axis=1)  # neighbours near the line through the point and neighbour j
    return inliers.max(axis=1) >= share * k


def on_boundary(cloud: np.ndarray, tol: float) -> np.ndarray:
    """Which points of a cloud sample the object's boundary, ``(n,)`` bool: in 2D its outline
    (:func:`split_outline`; the rest are samples of the sheet's surface, inside the outline), in 3D
    every point (a range cloud samples the body's visible surface)."""
    cloud = np.asarray(cloud, float)
    return split_outline(cloud, tol) if cloud.shape[1] == 2 else np.ones(len(cloud), bool)


def seen_nodes(nodes: np.ndarray, cloud: np.ndarray, tol: float) -> np.ndarray:
    """``(n,)`` bool: the nodes within ``tol`` (length) of a cloud, i.e. on the part of the surface
    a range camera saw (the reference cloud against the reference nodes)."""
    d, _ = cKDTree(np.asarray(cloud, float)).query(np.asarray(nodes, float))
    return d <= tol


def point_spacing(cloud: np.ndarray) -> float:
    """Median distance from a point to its nearest neighbour (length unit)."""
    if len(cloud) < 2:
        return 0.0
    d, _ = cKDTree(cloud).query(cloud, 2)
    return float(np.median(d[:, 1]))
