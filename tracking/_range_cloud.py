"""Unlabelled 3D point clouds from range images (no painted pattern needed), thinned to a spacing.

The thinning grid is a grid of square cells of pixels (a column of space along each cell's rays),
not a grid of cubes in space: a range image sees one surface per pixel, and cubes would sort the
pixels of a tilted surface into cells by their noisy depth, biasing every cell's mean by up to
the noise. Each cell's point is the mean of its pixels' 3D points: the noise averages down (about
noise / sqrt(pixels per cell)), and on a surface of radius of curvature R the mean lies inside it
by at most spacing^2 / (8 R).
"""

from __future__ import annotations

import numpy as np

from ._camera import Camera
from ._errors import ImageError, OptionError


def cell_pixels(camera: Camera, spacing: float, depth: float) -> int:
    """The side of a thinning cell in pixels: ``spacing`` over the pixel's footprint at ``depth``
    (rounded, at least 1)."""
    if not (np.isfinite(spacing) and spacing > 0):
        raise OptionError(f"the cloud spacing must be a positive length, got {spacing!r}")
    return max(1, int(round(spacing / camera.footprint(depth))))


def range_cloud(range_image: np.ndarray, camera: Camera, spacing: float, mask: np.ndarray | None = None,
                depth: float | None = None, max_step: float | None = None) -> np.ndarray:
    """The surface a range image sees, as 3D points in the camera's world axes, one per cell.

    Every pixel with data (finite depth) inside ``mask`` is placed in 3D by ``camera``
    (:meth:`Camera.to_world`); the image is cut into square cells of :func:`cell_pixels` pixels
    (``spacing`` at ``depth``) from its top-left corner (the same cells in every frame), and each
    cell holding data gives the mean of its points whose depth lies within ``max_step`` of the
    cell's median depth (where a cell straddles an occluding edge, the surface seen by most of its
    pixels wins, and no point is invented between the two surfaces).

    Args:
        range_image: ``(rows, cols)`` depth, NaN where no data (:func:`tracking.load_range_images`).
        camera: the range camera.
        spacing: the points' spacing on the surface (seen square on), the camera's length unit.
        mask: ``(rows, cols)`` bool, the pixels to use (an ROI or a drawn mask); None: all.
        depth: the depth at which a cell spans ``spacing`` (perspective); None: the median depth.
        max_step: largest depth difference from the cell's median (length unit); None: spacing / 2
            (a surface tilted more than 45 degrees from the view keeps the middle of each cell, and
            at a crease the face most of the cell sees wins; give more where the depth noise is
            not well below spacing / 2).

    Returns:
        ``(m, 3)`` points, in the cells' row-major order.

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
    side = cell_pixels(camera, spacing, float(np.median(z[keep])) if depth is None else depth)
    cell = (rows // side) * (z.shape[1] // side + 1) + cols // side
    d = z[rows, cols]
    order = np.lexsort((d, cell))
    _, start, counts = np.unique(cell[order], return_index=True, return_counts=True)
    median = d[order][start + counts // 2]
    _, inverse = np.unique(cell, return_inverse=True)
    near = np.abs(d - median[inverse.ravel()]) <= (0.5 * spacing if max_step is None else max_step)
    points, cell = points[near], cell[near]
    _, inverse, counts = np.unique(cell, return_inverse=True, return_counts=True)
    sums = np.stack([np.bincount(inverse.ravel(), weights=points[:, a], minlength=len(counts)) for a in range(3)], 1)
    return sums / counts[:, None]
