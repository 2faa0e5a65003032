"""A vectorised z-buffer rasteriser of triangles in NumPy: which triangle each sample sees, where.

Triangles are given by their vertices' pixel coordinates (u = column, v = row, pixel centres at
integers, as :class:`tracking.Tracks`) and depths along the camera axis. Samples sit on a lattice
``supersample`` times finer than the pixels (sample (i, j) at u = (j + 0.5) / s - 0.5, v likewise),
so that an image can be averaged over each pixel's square. For every (triangle, sample in its
bounding box) pair the barycentric coordinates decide inside-ness; the nearest inside triangle
wins (a z-buffer, by one sort per chunk of pairs). Under a perspective camera, attributes are
interpolated perspective-correctly (barycentrics weighted by 1 / depth).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

MAX_PAIRS = 4_000_000  # (triangle, sample) pairs per chunk: bounds the memory (~0.5 GB of temporaries)


@dataclass(frozen=True)
class Raster:
    """What each sample sees.

    Attributes:
        triangle: ``(rows * s, cols * s)`` int, the index of the visible triangle, -1 where none.
        weights: ``(rows * s, cols * s, 3)`` the visible point's barycentric weights in its triangle
            (perspective-correct: an attribute given per vertex is ``sum(weights * values)``);
            0 where none.
        depth: ``(rows * s, cols * s)`` its depth, NaN where none.
        supersample: s.
    """

    triangle: np.ndarray
    weights: np.ndarray
    depth: np.ndarray
    supersample: int

    def interpolate(self, values: np.ndarray) -> np.ndarray:
        """Per-vertex ``values`` ``(n_triangles, 3, ...)`` at every sample, NaN where nothing is seen."""
        values = np.asarray(values, np.float64)
        seen = self.triangle >= 0
        out = np.full(self.triangle.shape + values.shape[2:], np.nan)
        w = self.weights[seen]
        out[seen] = np.einsum("mk,mk...->m...", w, values[self.triangle[seen]])
        return out


def rasterise(uv: np.ndarray, depth: np.ndarray, shape: tuple[int, int], supersample: int = 1,
              perspective: bool = False) -> Raster:
    """Rasterise triangles with a z-buffer.

    Args:
        uv: ``(n, 3, 2)`` vertices' pixel coordinates (u = column, v = row).
        depth: ``(n, 3)`` vertices' depths along the camera axis (positive in front of the camera).
        shape: the image's ``(rows, cols)`` in pixels.
        supersample: samples per pixel side.
        perspective: interpolate with 1 / depth (a pinhole camera); False: linearly (orthographic).

    Returns:
        :class:`Raster` of ``(rows * supersample, cols * supersample)`` samples.
    """
    s = int(supersample)
    rows, cols = shape[0] * s, shape[1] * s
    pts = (np.asarray(uv, np.float64) + 0.5) * s - 0.5           # sample coordinates
    z = np.asarray(depth, np.float64)
    front = np.all(np.isfinite(pts), axis=(1, 2)) & np.all(np.isfinite(z) & (z > 0 if perspective else True), axis=1)
    a, b, c = pts[:, 0], pts[:, 1], pts[:, 2]
    area = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    lo = np.ceil(pts.min(axis=1)).astype(np.int64)
    hi = np.floor(pts.max(axis=1)).astype(np.int64)
    lo = np.maximum(lo, 0)
    hi = np.minimum(hi, [cols - 1, rows - 1])
    width = np.where((front & (np.abs(area) > 1e-12))[:, None], np.maximum(hi - lo + 1, 0), 0)
    counts = width[:, 0] * width[:, 1]
    best = np.full(rows * cols, np.inf)
    tri = np.full(rows * cols, -1, np.int64)
    weights = np.zeros((rows * cols, 3))
    for chunk in _chunks(counts):
        _raster_chunk(chunk, counts, lo, width, a, b, c, area, z, perspective, cols, best, tri, weights)
    depth_out = np.where(tri >= 0, best, np.nan)
    return Raster(tri.reshape(rows, cols), weights.reshape(rows, cols, 3), depth_out.reshape(rows, cols), s)


def _chunks(counts: np.ndarray):
    """Index arrays of triangles whose pairs together stay under :data:`MAX_PAIRS`."""
    order = np.flatnonzero(counts > 0)
    total = np.cumsum(counts[order])
    start = 0
    while start < len(order):
        stop = int(np.searchsorted(total, total[start] - counts[order[start]] + MAX_PAIRS, side="right"))
        stop = max(stop, start + 1)
        yield order[start:stop]
        start = stop


def _raster_chunk(index, counts, lo, width, a, b, c, area, z, perspective, cols, best, tri, weights):
    n = counts[index]
    owner = np.repeat(index, n)
    local = np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)
    px = lo[owner, 0] + local % width[owner, 0]
    py = lo[owner, 1] + local // width[owner, 0]
    A, B, C = a[owner], b[owner], c[owner]
    inv = 1.0 / area[owner]
    l1 = ((px - A[:, 0]) * (C[:, 1] - A[:, 1]) - (py - A[:, 1]) * (C[:, 0] - A[:, 0])) * inv
    l2 = ((B[:, 0] - A[:, 0]) * (py - A[:, 1]) - (B[:, 1] - A[:, 1]) * (px - A[:, 0])) * inv
    l0 = 1.0 - l1 - l2
    tol = -1e-9
    inside = (l0 >= tol) & (l1 >= tol) & (l2 >= tol)
    lam = np.stack([l0, l1, l2], axis=1)[inside]
    owner, pixel = owner[inside], (py * cols + px)[inside]
    zt = z[owner]
    if perspective:
        w = lam / zt
        d = 1.0 / w.sum(axis=1)
        lam = w * d[:, None]
    else:
        d = (lam * zt).sum(axis=1)
    order = np.lexsort((d, pixel))                      # nearest first within each sample
    pixel, d, owner, lam = pixel[order], d[order], owner[order], lam[order]
    first = np.r_[True, pixel[1:] != pixel[:-1]]
    pixel, d, owner, lam = pixel[first], d[first], owner[first], lam[first]
    nearer = d < best[pixel]
    pixel = pixel[nearer]
    best[pixel], tri[pixel], weights[pixel] = d[nearer], owner[nearer], lam[nearer]
