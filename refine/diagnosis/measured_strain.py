"""The strain of the measured point cloud itself (the paper's Figs. 8, 10, 11 read the abnormal
region from the strain of the measured grid): per triangle of a Delaunay triangulation of the
reference points, from the three corners' displacements, no model involved.

Triangles that bridge a gap in the points (a hole, a concave outline, a patch of lost points)
are left out: an edge longer than ``max_edge`` (default 2.5 median edge lengths) spans no
material that was seen.
"""

from __future__ import annotations

import numpy as np
from jaxtyping import Float, Int
from scipy.spatial import Delaunay

from refine.bundle.roles import point_spacing

__all__ = ["equivalent", "equivalent_strain", "measured_strain", "point_spacing", "point_triangles",
           "triangle_gradients"]


def point_triangles(points: Float[np.ndarray, "n 2"], max_edge: float | None = None) -> Int[np.ndarray, "t 3"]:
    """Delaunay triangles of ``points (n, 2)``, counter-clockwise, without those having an edge
    longer than ``max_edge`` (length unit; default 2.5 median edge lengths) or a vanishing area."""
    points = np.asarray(points, float)
    tri = Delaunay(points).simplices
    P = points[tri]
    edge = np.linalg.norm(P - np.roll(P, -1, axis=1), axis=2).max(axis=1)
    # the median Delaunay edge, not the nearest-neighbour spacing: on irregular clouds most edges
    # are well longer than the nearest neighbour, and a gap is long against the typical edge
    all_edges = np.linalg.norm(P - np.roll(P, -1, axis=1), axis=2)
    limit = 2.5 * float(np.median(all_edges)) if max_edge is None else max_edge
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
        max_edge: longest triangle edge kept (default 2.5 median edge lengths of the triangulation).

    Returns ``(triangles (t, 3), E (..., t, 2, 2))``, dimensionless, NaN in triangles with a lost
    corner.

    Raises:
        ValueError: fewer than 3 points, or points or displacements of the wrong shape.
    """
    X, u = np.asarray(points, dtype=np.float64), np.asarray(displacements, dtype=np.float64)
    if X.ndim != 2 or X.shape[1] != 2 or len(X) < 3:
        raise ValueError(f"measured_strain needs at least 3 points of shape (n, 2), got {X.shape}")
    if u.shape[-2:] != X.shape:
        raise ValueError(f"displacements must have shape (..., {len(X)}, 2) like the points, got {u.shape}")
    triangles = point_triangles(points, max_edge)
    G = triangle_gradients(points, triangles, displacements)
    F = G + np.eye(2)
    return triangles, 0.5 * (np.swapaxes(F, -1, -2) @ F - np.eye(2))


def equivalent_strain(E: Float[np.ndarray, "... 2 2"]) -> Float[np.ndarray, "..."]:
    """A scalar size of a strain tensor: its Frobenius norm ``sqrt(E:E)`` (dimensionless)."""
    return np.sqrt(np.einsum("...ij,...ij->...", E, E))


def equivalent(E: Float[np.ndarray, "*batch 2 2"]) -> Float[np.ndarray, "*batch"]:
    """Von Mises equivalent of in-plane strains, sqrt(2/3 dev(E):dev(E)), with E_zz = 0 (the
    out-of-plane strain is not measured); comparable with, not equal to, the model's
    :func:`jaxfem.equivalent_strain`, which includes its E_zz."""
    E3 = np.zeros(E.shape[:-2] + (3, 3))
    E3[..., :2, :2] = E
    dev = E3 - np.trace(E3, axis1=-2, axis2=-1)[..., None, None] * np.eye(3) / 3.0
    return np.sqrt(2.0 / 3.0 * np.sum(dev * dev, axis=(-2, -1)))
