"""Sub-pixel crossings as the extremum of the smoothed ink (the Hessian alternative refiner).

Smoothed at about the line width, the ink peaks at a crossing: the point-symmetric cross of two
lines has zero gradient at its centre under any affine deformation. Newton steps
x <- x - H^-1 grad on the Gaussian-derivative images locate that peak (a saddle-point detector
for checkerboards does the same with an indefinite Hessian). Quality is the peak's sharpness,
the smaller eigenvalue of -H, relative to the median over all crossings of the frame (0..1).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from ._crossings import CrossingGuess, GridFrame, Refined


@dataclass(frozen=True)
class HessianRefiner:
    """Newton ascent to the maximum of the ink smoothed with ``scale`` x line width (px)."""

    scale: float = 0.7
    iterations: int = 8
    min_quality: float = 0.3

    def refine(self, frame: GridFrame, guess: CrossingGuess) -> Refined:
        sigma = max(0.8, self.scale * frame.line_width)
        orders = ((0, 1), (1, 0), (0, 2), (1, 1), (2, 0))    # (d/dy, d/dx) orders: gx gy gxx gxy gyy
        coefficients = [ndimage.spline_filter(ndimage.gaussian_filter(frame.ink, sigma, order=o,
                                                                      mode="nearest"))
                        for o in orders]
        xy = guess.xy.copy()
        for _ in range(self.iterations):
            gx, gy, hxx, hxy, hyy = self._at(coefficients, xy)
            det = hxx * hyy - hxy ** 2
            det = np.where(np.abs(det) < 1e-12, np.nan, det)
            step = np.stack([(hyy * gx - hxy * gy) / det, (-hxy * gx + hxx * gy) / det], axis=1)
            step = np.clip(step, -0.5 * sigma, 0.5 * sigma)
            xy = xy - step
        gx, gy, hxx, hxy, hyy = self._at(coefficients, xy)
        mean, diff = 0.5 * (hxx + hyy), np.sqrt(0.25 * (hxx - hyy) ** 2 + hxy ** 2)
        sharpness = -(mean + diff)                   # smaller eigenvalue of -H; > 0 at a maximum
        reference = np.nanmedian(sharpness) if np.any(np.isfinite(sharpness)) else 1.0
        quality = np.clip(np.nan_to_num(sharpness / reference), 0.0, 1.0)
        moved = np.linalg.norm(xy - guess.xy, axis=1)
        inside = frame.spline.inside(xy[:, 0], xy[:, 1], margin=0.5 * frame.pitch)
        ok = np.isfinite(xy).all(axis=1) & (quality >= self.min_quality) & inside
        ok &= moved < max(1.5, 0.5 * frame.line_width)
        return Refined(np.where(ok[:, None], xy, np.nan), quality, ok)

    @staticmethod
    def _at(coefficients, xy):
        coords = np.stack([xy[:, 1], xy[:, 0]])
        return [ndimage.map_coordinates(c, coords, order=3, prefilter=False, mode="mirror")
                for c in coefficients]


@dataclass(frozen=True)
class SnakeOnlyRefiner:
    """No refinement: the crossing of the row and column snakes (for comparison)."""

    def refine(self, frame: GridFrame, guess: CrossingGuess) -> Refined:
        ok = np.isfinite(guess.xy).all(axis=1)
        ok &= frame.spline.inside(guess.xy[:, 0], guess.xy[:, 1], margin=0.5 * frame.pitch)
        return Refined(np.where(ok[:, None], guess.xy, np.nan), ok.astype(float), ok)
