"""The competitors of benchmarks/trackers.py on the same 8-bit images and points: OpenCV's
pyramidal Lucas-Kanade and scikit-image's upsampled phase correlation (split from trackers.py)."""

from __future__ import annotations

import cv2
import numpy as np
from skimage.registration import phase_cross_correlation


def lucas_kanade(reference, target, points, start, window=21):
    """OpenCV pyramidal LK from ``points`` (n, 2) with initial positions ``start`` (n, 2).

    One pyramid level above the image: with a start within half a pixel more levels only let the
    grid's periodicity pull points to a neighbouring crossing (window 15 px suits the grid best).
    """
    p0 = points.astype(np.float32).reshape(-1, 1, 2)
    p1 = start.astype(np.float32).reshape(-1, 1, 2)
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-4)
    out, status, _ = cv2.calcOpticalFlowPyrLK(np.clip(reference, 0, 255).astype(np.uint8),
                                              np.clip(target, 0, 255).astype(np.uint8), p0, p1.copy(),
                                              winSize=(window, window), maxLevel=1, criteria=criteria,
                                              flags=cv2.OPTFLOW_USE_INITIAL_FLOW)
    out = out.reshape(-1, 2).astype(np.float64)
    out[status.ravel() == 0] = np.nan
    return out


def phase_correlation(reference, target, points, start, half=16):
    """Upsampled phase correlation of Hann-windowed patches around each point."""
    window = np.outer(np.hanning(2 * half), np.hanning(2 * half))
    out = np.full(points.shape, np.nan)
    rows, cols = reference.shape
    for k, ((x, y), (sx, sy)) in enumerate(zip(np.rint(points).astype(int), np.rint(start).astype(int))):
        if min(x, y, sx, sy) < half or max(x, sx) + half > cols or max(y, sy) + half > rows:
            continue
        a = reference[y - half:y + half, x - half:x + half]
        b = target[sy - half:sy + half, sx - half:sx + half]
        shift = phase_cross_correlation((a - a.mean()) * window, (b - b.mean()) * window,
                                        upsample_factor=100)[0]
        # the patch's content moved by -shift (rows, cols) from (sx, sy); the point keeps its offset
        offset = points[k] - (x, y)
        out[k] = (sx - shift[1] + offset[0], sy - shift[0] + offset[1])
    return out
