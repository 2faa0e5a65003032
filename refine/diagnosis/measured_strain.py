"""The strain the tracked points themselves show, before any model: a Green-Lagrange strain per
triangle of a Delaunay triangulation of the reference points.

Each triangle's three points define an affine motion, so its deformation gradient is exact for
the points (F = I + grad u with u linear over the triangle) and E = (F^T F - I) / 2. This is the
measured counterpart of the model's strain map: a model that explains the data shows the same
pattern. It is noisy (noise / spacing per component), with no smoothing.
"""

from __future__ import annotations

import numpy as np
from jaxtyping import Float, Int
from scipy.spatial import Delaunay

#: a Delaunay triangle whose longest edge exceeds this many median edge lengths is dropped: it
#: spans a hole, a notch or the concave part of the outline, where there is no material to measure
MAX_EDGE = 2.5


def measured_strain(points: Float[np.ndarray, "n 2"], displacements: Float[np.ndarray, "*frames n 2"]
                    ) -> tuple[Int[np.ndarray, "t 3"], Float[np.ndarray, "*frames t 2 2"]]:
    """Green-Lagrange strain of the tracked points per triangle.

    Args:
        points: reference positions ``(n, 2)``, length unit.
        displacements: their displacements ``(n, 2)`` or ``(frames, n, 2)``, length unit; NaN
            where a point was lost (its triangles get NaN in that frame).

    Returns:
        ``(triangles, E)``: ``triangles (t, 3)`` indices into ``points``, counter-clockwise, of
        the Delaunay triangulation of ``points`` less the triangles with an edge over
        :data:`MAX_EDGE` median edge lengths or of (near) zero area; ``E (t, 2, 2)`` or
        ``(frames, t, 2, 2)``, the in-plane Green-Lagrange strain (dimensionless) of each.

    Raises:
        ValueError: fewer than 3 points, or points or displacements of the wrong shape.
    """
    X = np.asarray(points, dtype=np.float64)
    u = np.asarray(displacements, dtype=np.float64)
    if X.ndim != 2 or X.shape[1] != 2 or len(X) < 3:
        raise ValueError(f"measured_strain needs at least 3 points of shape (n, 2), got {X.shape}")
    if u.shape[-2:] != X.shape:
        raise ValueError(f"displacements must have shape (..., {len(X)}, 2) like the points, got {u.shape}")
    tri = _triangles(X)
    # edge matrices of each triangle in the reference (columns x1 - x0, x2 - x0) and their inverse
    D = np.stack([X[tri[:, 1]] - X[tri[:, 0]], X[tri[:, 2]] - X[tri[:, 0]]], axis=-1)  # (t, 2, 2)
    Dinv = np.linalg.inv(D)
    du = np.stack([u[..., tri[:, 1], :] - u[..., tri[:, 0], :],
                   u[..., tri[:, 2], :] - u[..., tri[:, 0], :]], axis=-1)  # (..., t, 2, 2)
    F = np.eye(2) + du @ Dinv
    return tri, 0.5 * (np.swapaxes(F, -1, -2) @ F - np.eye(2))


def equivalent(E: Float[np.ndarray, "*batch 2 2"]) -> Float[np.ndarray, "*batch"]:
    """Von Mises equivalent of in-plane strains, sqrt(2/3 dev(E):dev(E)), with E_zz = 0 (the
    out-of-plane strain is not measured); comparable with, not equal to, the model's
    :func:`jaxfem.equivalent_strain`, which includes its E_zz."""
    E3 = np.zeros(E.shape[:-2] + (3, 3))
    E3[..., :2, :2] = E
    dev = E3 - np.trace(E3, axis1=-2, axis2=-1)[..., None, None] * np.eye(3) / 3.0
    return np.sqrt(2.0 / 3.0 * np.sum(dev * dev, axis=(-2, -1)))


def _triangles(X: np.ndarray) -> np.ndarray:
    tri = Delaunay(X).simplices.astype(np.int64)
    a, b, c = X[tri[:, 0]], X[tri[:, 1]], X[tri[:, 2]]
    area2 = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    tri[area2 < 0] = tri[area2 < 0][:, [0, 2, 1]]  # counter-clockwise
    edges = np.stack([np.linalg.norm(b - a, axis=1), np.linalg.norm(c - b, axis=1), np.linalg.norm(a - c, axis=1)], 1)
    longest = edges.max(axis=1)
    keep = (longest <= MAX_EDGE * np.median(edges)) & (np.abs(area2) > 1e-9 * longest**2)
    return tri[keep]
