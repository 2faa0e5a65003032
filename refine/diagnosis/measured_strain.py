"""The strain of the measured point cloud itself (the paper's Figs. 8, 10, 11 read the abnormal
region from the strain of the measured grid): per triangle of a Delaunay triangulation of the
reference points, from the three corners' displacements, no model involved.

Triangles that bridge a gap in the points (a hole, a concave outline, a patch of lost points)
are left out: an edge longer than ``max_edge`` (default 2.5 median point spacings) spans no
material that was seen.
"""

from __future__ import annotations

import numpy as np
from jaxtyping import Float, Int
from scipy.spatial import Delaunay, cKDTree


def point_spacing(points: Float[np.ndarray, "n 2"]) -> float:
    """Median distance of a point to its nearest neighbour (length unit)."""
    d, _ = cKDTree(points).query(points, k=2)
    return float(np.median(d[:, 1]))


def point_triangles(points: Float[np.ndarray, "n 2"], max_edge: float | None = None) -> Int[np.ndarray, "t 3"]:
    """Delaunay triangles of ``points (n, 2)``, counter-clockwise, without those having an edge
    longer than ``max_edge`` (length unit; default 2.5 median point spacings) or a vanishing area."""
    points = np.asarray(points, float)
    tri = Delaunay(points).simplices
    P = points[tri]
    edge = np.linalg.norm(P - np.roll(P, -1, axis=1), axis=2).max(axis=1)
    limit = 2.5 * point_spacing(points) if max_edge is None else max_edge
    a = P[:, 1] - P[:, 0]
    b = P[:, 2] - P[:, 0]
    area2 = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    tri = np.where((area2 < 0)[:, None], tri[:, [0, 2, 1]], tri)
    keep = (edge <= limit) & (np.abs(area2) > 1e-9 * limit**2)
    return tri[keep]


def triangle_gradients(points: Float[np.ndarray, "n 2"], triangles: Int[np.ndarray, "t 3"],
                       displacements: Float[np.ndarray, "... n 2"]) -> Float[np.ndarray, "... t 2 2"]:
    """Displacement gradient ``du/dX`` per triangle (constant over a linear triangle), for one
    frame ``(n, 2)`` or several ``(frames, n, 2)``; NaN where a corner was lost."""
    P = np.asarray(points, float)[triangles]  # (t, 3, 2)
    D = np.stack([P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]], axis=2)  # (t, 2, 2): columns are edges
    Dinv = np.linalg.inv(D)
    U = np.asarray(displacements, float)[..., triangles, :]  # (..., t, 3, 2)
    dU = np.stack([U[..., 1, :] - U[..., 0, :], U[..., 2, :] - U[..., 0, :]], axis=-1)  # (..., t, 2, 2)
    return dU @ Dinv


def measured_strain(points: Float[np.ndarray, "n 2"], displacements: Float[np.ndarray, "... n 2"],
                    max_edge: float | None = None) -> tuple[Int[np.ndarray, "t 3"], Float[np.ndarray, "... t 2 2"]]:
    """Green-Lagrange strain ``E = (F^T F - I) / 2`` of the measured point cloud, per triangle of
    a Delaunay triangulation of the reference ``points (n, 2)`` (:func:`point_triangles`).

    Args:
        points: reference positions, length unit.
        displacements: one frame ``(n, 2)`` or several ``(frames, n, 2)``, same unit; NaN where lost.
        max_edge: longest triangle edge kept (default 2.5 median point spacings).

    Returns ``(triangles (t, 3), E (..., t, 2, 2))``, dimensionless, NaN in triangles with a lost
    corner.
    """
    triangles = point_triangles(points, max_edge)
    G = triangle_gradients(points, triangles, displacements)
    F = G + np.eye(2)
    return triangles, 0.5 * (np.swapaxes(F, -1, -2) @ F - np.eye(2))


def equivalent_strain(E: Float[np.ndarray, "... 2 2"]) -> Float[np.ndarray, "..."]:
    """A scalar size of a strain tensor: its Frobenius norm ``sqrt(E:E)`` (dimensionless)."""
    return np.sqrt(np.einsum("...ij,...ij->...", E, E))
