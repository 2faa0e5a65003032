"""Distances between a deformed model and an unlabelled cloud: point-to-outline distances (JAX,
differentiable in the model's node positions), inside tests, a soft minimum, and the split of a
cloud into outline points and surface samples (SciPy's KD-tree, from the data alone).

2D: the model's outline is the chain of its boundary edges. The distance functions take
segments ``(A, B)`` of any dimension; a 3D body's surface (triangles) comes with the 3D issue.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
from scipy.spatial import cKDTree

import jaxfem as jf

from refine.exceptions import CorrespondenceError


def boundary_segments(mesh: jf.Mesh) -> np.ndarray:
    """The boundary edges of a 2D mesh (outer outline and holes) as corner-node pairs ``(n_seg, 2)``,
    each oriented with the material on its left (counter-clockwise cells), so that the outward
    normal of ``a -> b`` is ``(dy, -dx)``."""
    if mesh.dim != 2:
        raise CorrespondenceError("the correspondence-free fit handles 2D models for now (outline + surface "
                                  "samples); range clouds of 3D bodies come with the 3D issue")
    return np.ascontiguousarray(mesh.boundary_facets()[:, :2])


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


def point_spacing(cloud: np.ndarray) -> float:
    """Median distance from a point to its nearest neighbour (length unit)."""
    if len(cloud) < 2:
        return 0.0
    d, _ = cKDTree(cloud).query(cloud, 2)
    return float(np.median(d[:, 1]))
