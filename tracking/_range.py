"""Depth of tracked points from range images, without inventing values in the holes."""

from __future__ import annotations

import numpy as np

from . import _lost as lost_codes
from ._errors import OptionError, TrackingError
from ._tracks import Tracks


def _keys(t: np.ndarray) -> np.ndarray:
    """Keys' cubic convolution weights (a = -1/2) for the 4 taps at offsets -1, 0, 1, 2; t in [0, 1)."""
    a = -0.5

    def near(s):
        return (a + 2) * s ** 3 - (a + 3) * s ** 2 + 1

    def far(s):
        return a * s ** 3 - 5 * a * s ** 2 + 8 * a * s - 4 * a

    return np.stack([far(1 + t), near(t), near(1 - t), far(2 - t)], axis=-1)


def range_lookup(range_image: np.ndarray, positions: np.ndarray, order: int = 1,
                 invalid_value: float | None = None, explain: bool = False) -> tuple[np.ndarray, ...]:
    """Depth z at image positions, interpolated, with points over holes reported as lost.

    A point is lost when its position is NaN, when its interpolation support (2 x 2 pixels for
    ``order`` 1 = bilinear, 4 x 4 for ``order`` 3 = Keys bicubic convolution) leaves the image,
    or when any pixel of the support is NaN, infinite or equal to ``invalid_value``; its z is NaN.

    Args:
        range_image: (rows, cols) depth per pixel (any length unit), NaN where unmeasured.
        positions: (..., 2) image coordinates (x = column, y = row) in pixels.
        order: 1 (bilinear) or 3 (bicubic convolution; local, interpolating).
        invalid_value: the scanner's "no data" code, if it writes one instead of NaN.
        explain: also return why each point is lost.

    Returns:
        z (...) and lost (...) bool; with ``explain`` also reasons (...) int8 codes of
        ``tracking._lost``: ``NO_RANGE`` (a hole or no-data pixel in the support), ``OFF_RANGE``
        (the support leaves the image), ``NOT_SEEN`` (no position: NaN), 0 where measured.
    """
    z_image = np.asarray(range_image, dtype=np.float64)
    if z_image.ndim != 2:
        raise TrackingError(f"range image must be (rows, cols), got shape {z_image.shape}")
    if order not in (1, 3):
        raise OptionError(f"range_lookup order must be 1 (bilinear) or 3 (bicubic), got {order}")
    positions = np.asarray(positions, dtype=np.float64)
    if positions.shape[-1] != 2:
        raise TrackingError(f"positions must be (..., 2) (x, y), got shape {positions.shape}")
    bad = ~np.isfinite(z_image)
    if invalid_value is not None:
        bad |= z_image == invalid_value
    flat = positions.reshape(-1, 2)
    rows, cols = z_image.shape
    z = np.full(len(flat), np.nan)
    finite = np.isfinite(flat).all(axis=1)
    x, y = flat[finite, 0], flat[finite, 1]
    x0, y0 = np.floor(x).astype(np.int64), np.floor(y).astype(np.int64)
    taps = np.arange(2) if order == 1 else np.arange(-1, 3)
    wx = np.stack([1 - (x - x0), x - x0], axis=-1) if order == 1 else _keys(x - x0)
    wy = np.stack([1 - (y - y0), y - y0], axis=-1) if order == 1 else _keys(y - y0)
    cx, cy = x0[:, None] + taps[None, :], y0[:, None] + taps[None, :]
    inside = ((cx.min(axis=1) >= 0) & (cx.max(axis=1) < cols)
              & (cy.min(axis=1) >= 0) & (cy.max(axis=1) < rows))
    cxc, cyc = np.clip(cx, 0, cols - 1), np.clip(cy, 0, rows - 1)
    support = z_image[cyc[:, :, None], cxc[:, None, :]]                # (m, taps_y, taps_x)
    holes = bad[cyc[:, :, None], cxc[:, None, :]].any(axis=(1, 2))
    value = np.einsum("mi,mij,mj->m", wy, np.where(np.isfinite(support), support, 0.0), wx)
    good = inside & ~holes
    out = np.full(len(x), np.nan)
    out[good] = value[good]
    z[finite] = out
    codes = np.full(len(flat), lost_codes.NOT_SEEN, np.int8)
    codes[finite] = np.select([~inside, holes, ~np.isfinite(out)],
                              [lost_codes.OFF_RANGE, lost_codes.NO_RANGE, lost_codes.NO_RANGE], lost_codes.MEASURED)
    shape = positions.shape[:-1]
    z, lost = z.reshape(shape), (codes != lost_codes.MEASURED).reshape(shape)
    return (z, lost, codes.reshape(shape)) if explain else (z, lost)


def points_3d(tracks: Tracks, range_images, order: int = 1,
              invalid_value: float | None = None, explain: bool = False) -> tuple[np.ndarray, ...]:
    """3D coordinates (x, y, z) of tracked points per frame from one range image per frame.

    Args:
        tracks: tracks in pixels.
        range_images: (n_frames, rows, cols) depth images registered with the intensity images.

        explain: also return why each point is lost.

    Returns:
        xyz (n_frames, n, 3) with x, y in pixels and z in the range images' unit (NaN where
        lost), and lost (n_frames, n): lost in tracking or over a hole of the range data; with
        ``explain`` also reasons (n_frames, n) int8 (``tracking._lost`` codes): the tracker's
        ``meta["lost_reasons"]`` where tracking lost the point (``NOT_SEEN`` without them), else
        the range lookup's (``NO_RANGE``, ``OFF_RANGE``).
    """
    if tracks.units != "px":
        raise TrackingError("points_3d needs tracks in pixels (look the range images up before to_length)")
    if len(range_images) != tracks.n_frames:
        raise TrackingError(f"{len(range_images)} range images for {tracks.n_frames} frames")
    xyz = np.full((tracks.n_frames, tracks.n_points, 3), np.nan)
    lost = np.array(tracks.lost, copy=True)
    tracked = np.asarray(tracks.meta.get("lost_reasons", np.where(lost, lost_codes.NOT_SEEN, 0)), np.int8)
    reasons = np.where(lost, np.where(tracked == lost_codes.MEASURED, lost_codes.NOT_SEEN, tracked), 0).astype(np.int8)
    for f, range_image in enumerate(range_images):
        z, hole, why = range_lookup(range_image, tracks.positions[f], order, invalid_value, explain=True)
        reasons[f] = np.where(reasons[f] == lost_codes.MEASURED, why, reasons[f])  # the first reason
        lost[f] |= hole
        xyz[f, :, :2] = tracks.positions[f]
        xyz[f, :, 2] = z
    xyz[lost] = np.nan
    return (xyz, lost, reasons) if explain else (xyz, lost)
