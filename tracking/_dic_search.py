"""Integer-pixel initial guess for subset correlation: normalised cross-correlation in a window."""

from __future__ import annotations

import cv2
import numpy as np


def integer_search(reference: np.ndarray, target: np.ndarray, centres: np.ndarray, radius: int,
                   guess: np.ndarray, search: int) -> tuple[np.ndarray, np.ndarray]:
    """Integer displacement of each subset by zero-normalised cross-correlation.

    Args:
        reference, target: (rows, cols) images.
        centres: (n, 2) integer subset centres (x, y) in the reference.
        radius: subset half-size (px).
        guess: (n, 2) predicted displacement (px); the search window is centred on it.
        search: half-size of the search range around the guess (px).

    Returns:
        displacement (n, 2) in whole pixels (NaN where the window leaves the image) and the
        correlation peak (n,) in [-1, 1].
    """
    rows, cols = reference.shape
    ref32 = reference.astype(np.float32)
    tgt32 = target.astype(np.float32)
    out = np.full((len(centres), 2), np.nan)
    peak = np.full(len(centres), -1.0)
    for k, ((cx, cy), (gx, gy)) in enumerate(zip(np.rint(centres).astype(int), np.rint(guess).astype(int))):
        if cx - radius < 0 or cy - radius < 0 or cx + radius >= cols or cy + radius >= rows:
            continue
        # the search window, clipped to the image; it must still hold the whole subset
        x0, y0 = max(cx + gx - radius - search, 0), max(cy + gy - radius - search, 0)
        x1 = min(cx + gx + radius + search + 1, cols)
        y1 = min(cy + gy + radius + search + 1, rows)
        if x1 - x0 < 2 * radius + 1 or y1 - y0 < 2 * radius + 1:
            continue
        template = ref32[cy - radius:cy + radius + 1, cx - radius:cx + radius + 1]
        score = cv2.matchTemplate(tgt32[y0:y1, x0:x1], template, cv2.TM_CCOEFF_NORMED)
        iy, ix = np.unravel_index(int(np.argmax(score)), score.shape)
        out[k] = (x0 + ix + radius - cx, y0 + iy + radius - cy)
        peak[k] = float(score[iy, ix])
    return out, peak
