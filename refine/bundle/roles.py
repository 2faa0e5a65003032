"""The roles of tracked points in a refinement, and how they are assigned.

The paper (Tsap, Goldgof & Sarkar 2000, Sec. 1.3 and 2.1) splits the correspondences into a set P
that drives the model (role ``boundary``), a set Q that guides the search (``guide``) and a
held-out set for validation (``validate``). :data:`ROLES` is the one list of them that the bundle
format, the observations and the commands read.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage
from scipy.spatial import ConvexHull, cKDTree

from refine.exceptions import ObservationError

ROLES = ("boundary", "guide", "validate")


def point_spacing(points: np.ndarray) -> float:
    """Median nearest-neighbour distance of ``points`` ``(n, dim)``, n >= 2, in their length unit."""
    d, _ = cKDTree(points).query(points, k=2)
    return float(np.median(d[:, 1]))


def assign_roles(points_xy: np.ndarray, validate_fraction: float = 0.2, seed: int = 0,
                 grid_index: np.ndarray | None = None) -> np.ndarray:
    """Role of every point: "boundary", "guide" or "validate", (n,) array of str.

    Boundary points are the outer ring of the tracked region: the lattice points next to the
    outside of the lattice's outline when ``grid_index`` (n, 2) is given (holes inside the region
    do not count), otherwise the points on the convex hull's edges. Of the interior points, a
    seeded random ``validate_fraction`` (rounded) is held out for validation; the rest guide.

    Args:
        points_xy: (n, 2) reference positions.
        validate_fraction: in [0, 1].
        seed: random seed of the validation draw.
        grid_index: optional (n, 2) (row, col) of the points (e.g. ``tracking.Tracks.grid_index``).

    Raises:
        ObservationError: ``points_xy`` is not (n, 2) with n > 0, or ``validate_fraction`` is
            outside [0, 1].
    """
    points = np.asarray(points_xy, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 2 or len(points) == 0:
        raise ObservationError(f"points must be (n, 2) with n > 0, got shape {points.shape}")
    if not 0.0 <= validate_fraction <= 1.0:
        raise ObservationError(f"validate_fraction must be in [0, 1], got {validate_fraction}")
    if grid_index is not None and np.all(np.asarray(grid_index) >= 0):
        boundary = _ring_from_topology(np.asarray(grid_index, dtype=np.int64))
    else:
        boundary = _ring_from_hull(points)
    roles = np.where(boundary, "boundary", "guide").astype("<U8")
    interior = np.nonzero(~boundary)[0]
    count = int(round(validate_fraction * len(interior)))
    chosen = np.random.default_rng(seed).choice(interior, size=count, replace=False)
    roles[chosen] = "validate"
    return roles


def _ring_from_topology(grid_index: np.ndarray) -> np.ndarray:
    """Points of a lattice with an 8-neighbour outside the lattice's outer outline."""
    index = grid_index - grid_index.min(axis=0)
    occupied = np.zeros(tuple(index.max(axis=0) + 3), bool)
    occupied[index[:, 0] + 1, index[:, 1] + 1] = True
    empty, _ = ndimage.label(~occupied)
    outside = np.isin(empty, np.unique(np.concatenate([empty[0], empty[-1], empty[:, 0], empty[:, -1]])))
    outside &= ~occupied
    near_outside = ndimage.binary_dilation(outside, structure=np.ones((3, 3), bool))
    return near_outside[index[:, 0] + 1, index[:, 1] + 1]


def _ring_from_hull(points: np.ndarray) -> np.ndarray:
    """Points on (or within a quarter spacing of) the edges of the convex hull."""
    if len(points) < 4:
        return np.ones(len(points), bool)
    spacing = point_spacing(points)
    try:
        hull = ConvexHull(points)
    except Exception:  # noqa: BLE001 - collinear points: all of them are on the boundary
        return np.ones(len(points), bool)
    distance = np.min(np.abs(points @ hull.equations[:, :2].T + hull.equations[:, 2]), axis=1)
    return distance <= 0.25 * spacing
