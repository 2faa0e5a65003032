"""Unlabelled 3D point clouds from range images (no painted pattern needed), thinned on a voxel grid."""

from __future__ import annotations

import numpy as np

from ._camera import Camera
from ._errors import ImageError, OptionError


def voxel_thin(points: np.ndarray, spacing: float) -> np.ndarray:
    """One point per occupied voxel: the mean of the points in each cube of side ``spacing``.

    The cubes are those of the grid with a corner at the origin (the same grid in every frame).
    Averaging also averages the depth noise (about noise / sqrt(points per voxel)); on a curved
    surface the mean lies inside the curve by at most spacing^2 / (8 R) (R the radius of curvature).

    Args:
        points: ``(n, 3)`` length unit, finite.
        spacing: voxel side, same unit (> 0).

    Returns:
        ``(m, 3)`` points, m <= n, sorted by voxel.
    """
    if not (np.isfinite(spacing) and spacing > 0):
        raise OptionError(f"the cloud spacing must be a positive length, got {spacing!r}")
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(points) == 0:
        return points
    cells = np.floor(points / spacing).astype(np.int64)
    _, inverse, counts = np.unique(cells, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    sums = np.stack([np.bincount(inverse, weights=points[:, a], minlength=len(counts)) for a in range(3)], axis=1)
    return sums / counts[:, None]


def range_cloud(range_image: np.ndarray, camera: Camera, spacing: float, mask: np.ndarray | None = None) -> np.ndarray:
    """The surface a range image sees, as 3D points in the camera's world axes, thinned to ``spacing``.

    Every pixel with data (finite depth) inside ``mask`` is placed in 3D by ``camera``
    (:meth:`Camera.to_world`), then :func:`voxel_thin` keeps one point (the mean) per voxel.

    Args:
        range_image: ``(rows, cols)`` depth, NaN where no data (:func:`tracking.load_range_images`).
        camera: the range camera.
        spacing: voxel side, the camera's length unit.
        mask: ``(rows, cols)`` bool, the pixels to use (an ROI or a drawn mask); None: all.

    Returns:
        ``(m, 3)`` points.

    Raises:
        ImageError: no pixel with data lies in the mask.
    """
    z = np.asarray(range_image, dtype=np.float64)
    keep = np.isfinite(z)
    if mask is not None:
        mask = np.asarray(mask, bool)
        if mask.shape != z.shape:
            raise ImageError(f"the cloud mask has shape {mask.shape}, the range image {z.shape}")
        keep &= mask
    if not keep.any():
        raise ImageError("no pixel with range data lies in the region of interest / mask")
    rows, cols = np.nonzero(keep)
    points = camera.to_world(np.stack([cols, rows], axis=1).astype(np.float64), z[rows, cols])
    return voxel_thin(points, spacing)
