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
    AB = B - A
    t = jnp.einsum("pmd,md->pm", P[:, None, :] - A[None], AB) / jnp.maximum(jnp.sum(AB * AB, axis=1), 1e-30)
    closest = A[None] + jnp.clip(t, 0.0, 1.0)[..., None] * AB[None]
    return jnp.sqrt(jnp.sum((P[:, None, :] - closest) ** 2, axis=-1) + 1e-18)


def triangle_distances(P, A, B, C):
    """Distances from every point to every triangle, ``(n_points, n_triangles)``.

    Args:
        P: ``(n, 3)`` points; A, B, C: ``(m, 3)`` the triangles' corners. A point whose projection
            falls inside a triangle is at its distance to the plane, any other at its distance to
            the nearest edge. Differentiable in all four (piecewise smooth).
    """
    n = jnp.cross(B - A, C - A)
    nn = jnp.maximum(jnp.sum(n * n, axis=1), 1e-30)
    d = P[:, None, :] - A[None]  # (p, m, 3)
    # barycentric coordinates of the projection: signs of the sub-triangles' normals along n
    s_c = jnp.einsum("pmd,md->pm", jnp.cross(B - A, d), n) / nn
    s_a = jnp.einsum("pmd,md->pm", jnp.cross(C - B, P[:, None, :] - B[None]), n) / nn
    s_b = 1.0 - s_a - s_c
    within = (s_a >= 0) & (s_b >= 0) & (s_c >= 0)
    plane = jnp.einsum("pmd,md->pm", d, n) / jnp.sqrt(nn)
    edges = jnp.minimum(jnp.minimum(segment_distances(P, A, B), segment_distances(P, B, C)),
                        segment_distances(P, C, A))
    return jnp.where(within, jnp.sqrt(plane * plane + 1e-18), edges)


def facet_distances(P, x, facets):
    """Distances ``(n_points, n_facets)`` from points ``P (n, dim)`` to the facets ``(m, 2 or 3)``
    (node indices: segments in 2D, triangles in 3D) of node positions ``x (n_nodes, dim)``."""
    if facets.shape[1] == 2:
        return segment_distances(P, x[facets[:, 0]], x[facets[:, 1]])
    return triangle_distances(P, x[facets[:, 0]], x[facets[:, 1]], x[facets[:, 2]])


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
