"""What a crossing refiner receives and returns; refiners are plug-ins with one method.

A refiner is any object with ``refine(frame: GridFrame, guess: CrossingGuess) -> Refined``;
:data:`REFINERS` maps the names accepted by the grid tracker to them.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ._interp import SplineImage, spline_image


@dataclass(frozen=True)
class GridFrame:
    """One image of a grid sequence with what refiners need from it.

    Attributes:
        image: (rows, cols) float64 grey values.
        ink: (rows, cols) lines as positive ridges (see ``_lattice.ink_image``).
        line_width: line width in pixels (full width at half depth, blur included).
        pitch: reference grid pitch in pixels.
    """

    image: np.ndarray
    ink: np.ndarray
    line_width: float
    pitch: float

    @cached_property
    def spline(self) -> SplineImage:
        return spline_image(self.image, order=5)


@dataclass(frozen=True)
class CrossingGuess:
    """Initial crossings and the local lines through them, N crossings.

    Attributes:
        xy: (N, 2) positions (px).
        row_dir: (N, 2) unit direction of the grid row line through the crossing (about +x).
        col_dir: (N, 2) unit direction of the grid column line (about +y).
        row_spacing: (N, 2) distance to the previous / next crossing along the row (NaN: none).
        col_spacing: (N, 2) distance to the previous / next crossing along the column.
    """

    xy: np.ndarray
    row_dir: np.ndarray
    col_dir: np.ndarray
    row_spacing: np.ndarray
    col_spacing: np.ndarray


@dataclass(frozen=True)
class Refined:
    """Refined crossings: xy (N, 2), quality (N,) (higher is better), ok (N,) bool."""

    xy: np.ndarray
    quality: np.ndarray
    ok: np.ndarray


def spacing_or(spacing: np.ndarray, default: float) -> np.ndarray:
    """(N, 2) spacings with a missing side replaced by the other side, then by ``default``.

    Spacings are kept within 0.6-1.6 times the median of the given ones (a snake caught on a
    blemish must not shrink or stretch the fitting windows).
    """
    out = np.array(spacing, dtype=np.float64)
    out[:, 0] = np.where(np.isfinite(out[:, 0]), out[:, 0], out[:, 1])
    out[:, 1] = np.where(np.isfinite(out[:, 1]), out[:, 1], out[:, 0])
    typical = np.nanmedian(out) if np.any(np.isfinite(out)) else default
    return np.clip(np.where(np.isfinite(out), out, default), 0.6 * typical, 1.6 * typical)
