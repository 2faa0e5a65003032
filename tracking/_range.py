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


def _plane_filled(support: np.ndarray) -> np.ndarray:
    """2 x 2 supports (m, 2, 2) with one NaN corner filled from the plane through the other three
    (adjacent + adjacent - opposite); supports with two or more NaN corners keep them."""
    flip_i, flip_j, opposite = support[:, ::-1, :], support[:, :, ::-1], support[:, ::-1, ::-1]
    one_missing = (np.isnan(support).sum(axis=(1, 2)) == 1)[:, None, None]
    return np.where(np.isnan(support) & one_missing, flip_i + flip_j - opposite, support)


def _quadratic_fit(support: np.ndarray, dx: np.ndarray, dy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares quadratic through the valid pixels of windows ``support`` (m, T, T) (NaN: no
    data), ``dx`` (m, T) / ``dy`` (m, T) the pixels' offsets from the point: its value at the point
    (m,), and whether the fit is determined (at least half the window valid, not degenerate)."""
    X, Y = dx[:, None, :], dy[:, :, None]
    basis = np.stack(np.broadcast_arrays(np.ones_like(X * Y), X, Y, X * X, X * Y, Y * Y), axis=-1)  # (m, T, T, 6)
    valid = ~np.isnan(support)
    w = valid[..., None] * basis
    normal = np.einsum("mijk,mijl->mkl", w, basis)
    rhs = np.einsum("mijk,mij->mk", w, np.nan_to_num(support))
    enough = valid.sum(axis=(1, 2)) >= max(6, support.shape[1] ** 2 // 2)
    ok = enough & (np.linalg.cond(normal) < 1e8)
    value = np.full(len(support), np.nan)
    if ok.any():
        value[ok] = np.linalg.solve(normal[ok], rhs[ok][..., None])[:, 0, 0]
    return value, ok


def range_lookup(range_image: np.ndarray, positions: np.ndarray, order: int = 1,
                 invalid_value: float | None = None, explain: bool = False,
                 max_step: float | None = None, radius: int = 2) -> tuple[np.ndarray, ...]:
    """Depth z at image positions, interpolated from valid pixels only, with points over holes lost.

    ``order`` 1 (bilinear) uses the 2 x 2 pixels around the point; where one of them has no data
    but the pixel nearest the point has, the missing value is taken on the plane through the other
    three (so the interpolation uses valid neighbours only and is still exact on a plane). ``order``
    3 (Keys bicubic convolution, 4 x 4 pixels) needs every pixel of its support. ``order`` 2 fits a
    quadratic z(x, y) by least squares to the valid pixels of the (2 ``radius`` + 1)^2 window around
    the pixel nearest the point (at least half of them valid, the nearest one among them) and
    evaluates it at the point: exact on quadrics, and it averages the depth noise down (by about
    2.5 for ``radius`` 2, where bilinear averages 4 pixels at best) at the price of smoothing
    features narrower than the window. A point is lost
    when its position is NaN, when its support leaves the image, when its support lacks more data
    than that (a pixel NaN, infinite or equal to ``invalid_value``), or, with ``max_step``, when the
    depths of its support spread by more than ``max_step`` (an occluding edge: two surfaces meet
    in the support, and interpolating between them would invent a point on neither); its z is NaN.

    Args:
        range_image: (rows, cols) depth per pixel (any length unit), NaN where unmeasured.
        positions: (..., 2) image coordinates (x = column, y = row) in pixels.
        order: 1 (bilinear), 2 (local least-squares quadratic) or 3 (bicubic convolution).
        invalid_value: the scanner's "no data" code, if it writes one instead of NaN.
        explain: also return why each point is lost.
        max_step: largest depth spread within a point's support (None: no edge test).
        radius: half side of the window of ``order`` 2, px.

    Returns:
        z (...) and lost (...) bool; with ``explain`` also reasons (...) int8 codes of
        ``tracking._lost``: ``NO_RANGE`` (a hole or no-data pixel in the support), ``OFF_RANGE``
        (the support leaves the image), ``RANGE_EDGE`` (depth jump over ``max_step``),
        ``NOT_SEEN`` (no position: NaN), 0 where measured.
    """
    z_image = np.asarray(range_image, dtype=np.float64)
    if z_image.ndim != 2:
        raise TrackingError(f"range image must be (rows, cols), got shape {z_image.shape}")
    if order not in (1, 2, 3):
        raise OptionError(f"range_lookup order must be 1 (bilinear), 2 (quadratic fit) or 3 (bicubic), got {order}")
    if order == 2 and not (isinstance(radius, (int, np.integer)) and radius >= 1):
        raise OptionError(f"range_lookup radius must be a whole number of pixels >= 1, got {radius!r}")
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
    round_ = np.rint if order == 2 else np.floor              # order 2: the window centred on the nearest pixel
    x0, y0 = round_(x).astype(np.int64), round_(y).astype(np.int64)
    taps = {1: np.arange(2), 2: np.arange(-radius, radius + 1), 3: np.arange(-1, 3)}[order]
    wx = np.stack([1 - (x - x0), x - x0], axis=-1) if order == 1 else _keys(x - x0)
    wy = np.stack([1 - (y - y0), y - y0], axis=-1) if order == 1 else _keys(y - y0)
    cx, cy = x0[:, None] + taps[None, :], y0[:, None] + taps[None, :]
    inside = ((cx.min(axis=1) >= 0) & (cx.max(axis=1) < cols)
              & (cy.min(axis=1) >= 0) & (cy.max(axis=1) < rows))
    cxc, cyc = np.clip(cx, 0, cols - 1), np.clip(cy, 0, rows - 1)
    support = np.where(bad, np.nan, z_image)[cyc[:, :, None], cxc[:, None, :]]   # (m, taps_y, taps_x)
    if order == 1:
        nearest = ~np.isnan(support[np.arange(len(x)), np.rint(y - y0).astype(int), np.rint(x - x0).astype(int)])
        support = _plane_filled(support)
        holes = ~nearest | np.isnan(support).any(axis=(1, 2))
    elif order == 2:
        value, fitted = _quadratic_fit(support, taps[None, :] - (x - x0)[:, None], taps[None, :] - (y - y0)[:, None])
        holes = np.isnan(support[:, radius, radius]) | ~fitted
    else:
        holes = np.isnan(support).any(axis=(1, 2))
    if order != 2:
        value = np.einsum("mi,mij,mj->m", wy, np.nan_to_num(support), wx)
    spread = (np.where(np.isnan(support), -np.inf, support).max(axis=(1, 2))
              - np.where(np.isnan(support), np.inf, support).min(axis=(1, 2)))
    edge = ~holes & (spread > max_step) if max_step is not None else np.zeros(len(x), bool)
    good = inside & ~holes & ~edge
    out = np.full(len(x), np.nan)
    out[good] = value[good]
    z[finite] = out
    codes = np.full(len(flat), lost_codes.NOT_SEEN, np.int8)
    codes[finite] = np.select([~inside, holes, edge, ~np.isfinite(out)],
                              [lost_codes.OFF_RANGE, lost_codes.NO_RANGE, lost_codes.RANGE_EDGE, lost_codes.NO_RANGE],
                              lost_codes.MEASURED)
    shape = positions.shape[:-1]
    z, lost = z.reshape(shape), (codes != lost_codes.MEASURED).reshape(shape)
    return (z, lost, codes.reshape(shape)) if explain else (z, lost)


def points_3d(tracks: Tracks, range_images, order: int = 1, invalid_value: float | None = None,
              explain: bool = False, camera=None, max_step: float | None = None,
              radius: int = 2) -> tuple[np.ndarray, ...]:
    """3D coordinates (x, y, z) of tracked points per frame from one range image per frame.

    Each point's depth is looked up in its own frame's range image at its tracked (sub-pixel)
    position (:func:`range_lookup`, with ``order``, ``invalid_value``, ``max_step`` and ``radius``).

    Args:
        tracks: tracks in pixels.
        range_images: (n_frames, rows, cols) depth images registered with the intensity images.
        camera: a :class:`tracking.Camera` that turns pixel and depth into 3D points (its length
            unit, its world axes); None: x, y stay in pixels and z is the depth.
        explain: also return why each point is lost.

    Returns:
        xyz (n_frames, n, 3) (NaN where lost), and lost (n_frames, n): lost in tracking or over a
        hole of the range data; with ``explain`` also reasons (n_frames, n) int8
        (``tracking._lost`` codes): the tracker's ``meta["lost_reasons"]`` where tracking lost the
        point (``NOT_SEEN`` without them), else the range lookup's (``NO_RANGE``, ``OFF_RANGE``,
        ``RANGE_EDGE``).
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
        z, hole, why = range_lookup(range_image, tracks.positions[f], order, invalid_value, explain=True,
                                    max_step=max_step, radius=radius)
        reasons[f] = np.where(reasons[f] == lost_codes.MEASURED, why, reasons[f])  # the first reason
        lost[f] |= hole
        if camera is None:
            xyz[f, :, :2] = tracks.positions[f]
            xyz[f, :, 2] = z
        else:
            xyz[f] = camera.to_world(tracks.positions[f], z)
    xyz[lost] = np.nan
    return (xyz, lost, reasons) if explain else (xyz, lost)
