"""The grid tracker: crossings of a painted grid, found with snakes and refined to sub-pixels.

Reference frame: the lattice (pitch, orientation, polarity, line width) comes from the image
spectrum, crossing candidates from the smoothed ink, their (row, column) from growing the
lattice from the centre of the region of interest; snakes on the row and column lines give the
crossings, which a refiner (default: symmetric line fitting) brings to sub-pixel accuracy.
Later frames: each crossing's position is predicted (constant velocity, neighbours for lost
ones), corrected ring by ring from detected crossings, then snakes and the refiner run again.
A crossing is lost in a frame when the refiner rejects it (poor symmetry, moved too far, near
the image border) or when its motion disagrees with its neighbours' by more than ``max_jump``
pitches; it is looked for again in the next frame.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ._crossings import CrossingGuess, GridFrame, Refined
from ._errors import GridNotFoundError, OptionError
from ._grid_motion import jumps, predict, propagate
from ._grid_topology import crossing_candidates, fill_positions, interior_gaps, label_grid, lattice_spacing
from ._images import as_stack, inside_mask, roi_mask
from ._lattice import GridGeometry, grid_geometry, ink_image
from ._refine_hessian import HessianRefiner, SnakeOnlyRefiner
from ._refine_lines import LineFitRefiner
from ._snake import SnakeOptions, snake_crossings
from ._tracks import Tracks

REFINERS = {"lines": LineFitRefiner, "hessian": HessianRefiner, "snake": SnakeOnlyRefiner}


@dataclass(frozen=True)
class GridTracker:
    """Track the crossings of a grid of lines (dark on light or light on dark), pitch ~4-80 px.

    Attributes:
        refiner: sub-pixel method, "lines" (symmetric line fitting, the most accurate),
            "hessian" (extremum of the smoothed ink) or "snake" (snake crossings only).
        pitch_range: (min, max) grid pitch in pixels to look for in the reference image.
        dark_lines: True/False to force the polarity, None to detect it.
        snake: settings of the active contours.
        max_jump: largest difference, in pitches, between a crossing's motion in one frame and
            its neighbours' before it is declared lost (an identity swap guard).
        min_quality: refiner quality under which a crossing is lost (None: the refiner's own).
        line_shape: centre lines of the "lines" refiner: "adaptive" (a parabola per line where
            the data ask for it, e.g. at a stiff inclusion's edge), "straight" or "curved".
    """

    refiner: str = "lines"
    pitch_range: tuple[float, float] = (4.0, 80.0)
    dark_lines: bool | None = None
    snake: SnakeOptions = field(default_factory=SnakeOptions)
    max_jump: float = 0.3
    min_quality: float | None = None
    line_shape: str = "adaptive"

    def _refiner(self):
        if self.refiner not in REFINERS:
            raise OptionError(f"unknown grid refiner {self.refiner!r}; use one of {sorted(REFINERS)}")
        kind = REFINERS[self.refiner]
        options = {} if self.min_quality is None or kind is SnakeOnlyRefiner else {"min_quality": self.min_quality}
        if kind is LineFitRefiner:
            options["shape"] = self.line_shape
        return kind(**options)

    def track(self, images, roi=None) -> Tracks:
        """Track the grid crossings through ``images`` (sequence of (rows, cols) or paths).

        Args:
            roi: (x0, y0, x1, y1) pixels of the first image, a mask, or None for all of it.
                Crossings of the first image inside it are tracked.

        Returns:
            Tracks with ``grid_index`` (row, col) and ``quality_kind`` the refiner's score.
        """
        stack = as_stack(images)
        mask = roi_mask(roi, stack.shape[1:])
        refiner = self._refiner()
        geometry = grid_geometry(stack[0], mask, self.pitch_range, self.dark_lines)
        nodes, quality = self._reference(stack[0], mask, geometry, refiner)
        active = np.isfinite(nodes[..., 0])
        history = [nodes]
        qualities = [quality]
        for image in stack[1:]:
            positions, quality = self._frame(image, history, active, geometry, refiner)
            history.append(positions)
            qualities.append(quality)
        return self._tracks(history, qualities, active, geometry)

    def _reference(self, image, mask, geometry: GridGeometry, refiner):
        ink = ink_image(image, geometry)
        candidates = crossing_candidates(ink, geometry.pitch, mask)
        rows, cols = np.nonzero(mask)
        nodes = label_grid(candidates, geometry, (cols.mean(), rows.mean()))
        valid = np.isfinite(nodes[..., 0])
        gaps = interior_gaps(valid)
        if gaps.any():
            filled = fill_positions(nodes, valid)
            gaps &= inside_mask(mask, filled.reshape(-1, 2)).reshape(gaps.shape)
            nodes = np.where(gaps[..., None], filled, nodes)
        frame = GridFrame(image, ink, geometry.line_width, geometry.pitch)
        positions, quality, ok = self._measure(frame, nodes, valid | gaps, geometry, refiner)
        ok &= inside_mask(mask, np.nan_to_num(positions, nan=-1.0).reshape(-1, 2)).reshape(ok.shape)
        if np.count_nonzero(ok) < 4:
            raise GridNotFoundError(
                f"only {np.count_nonzero(ok)} grid crossings could be measured in the reference image; "
                "check the ROI and that the grid lines are visible")
        positions[~ok] = np.nan
        return positions, quality

    def _frame(self, image, history, active, geometry: GridGeometry, refiner):
        predicted = predict(history, active)
        ink = ink_image(image, geometry)
        candidates = crossing_candidates(ink, geometry.pitch)
        coarse, _ = propagate(predicted, active, candidates, radius=0.3 * geometry.pitch)
        frame = GridFrame(image, ink, geometry.line_width, geometry.pitch)
        positions, quality, ok = self._measure(frame, coarse, active, geometry, refiner)
        last = history[-1]
        step = np.where(np.isfinite(last), positions - last, positions - predicted)
        ok &= ~jumps(step, ok, self.max_jump * geometry.pitch)
        positions[~ok] = np.nan
        return positions, quality

    def _measure(self, frame: GridFrame, nodes, use, geometry: GridGeometry, refiner):
        """Snakes then refiner on the nodes in ``use``: positions (R, C, 2), quality, ok (R, C)."""
        crossing, row_dir, col_dir = snake_crossings(
            frame.ink, nodes, use, geometry.pitch, geometry.line_width,
            (geometry.col_step, geometry.row_step), self.snake)
        # neighbours beyond the image border give no spacing (their snakes end at the border)
        seen = frame.spline.inside(crossing[..., 0], crossing[..., 1], margin=1.0)
        row_gap, col_gap = lattice_spacing(np.where(seen[..., None], crossing, np.nan))
        flat = use.ravel()
        guess = CrossingGuess(crossing.reshape(-1, 2)[flat], row_dir.reshape(-1, 2)[flat],
                              col_dir.reshape(-1, 2)[flat], row_gap.reshape(-1, 2)[flat],
                              col_gap.reshape(-1, 2)[flat])
        bad = ~np.isfinite(guess.xy).all(axis=1)
        guess = CrossingGuess(np.where(bad[:, None], nodes.reshape(-1, 2)[flat], guess.xy), guess.row_dir,
                              guess.col_dir, guess.row_spacing, guess.col_spacing)
        result: Refined = refiner.refine(frame, guess)
        positions = np.full(nodes.shape, np.nan)
        quality = np.zeros(use.shape)
        ok = np.zeros(use.shape, bool)
        positions.reshape(-1, 2)[flat] = result.xy
        quality.reshape(-1)[flat] = result.quality
        ok.reshape(-1)[flat] = result.ok & ~bad
        return positions, quality, ok

    def _tracks(self, history, qualities, active, geometry: GridGeometry) -> Tracks:
        ii, jj = np.nonzero(active)
        positions = np.stack([h[ii, jj] for h in history])
        lost = ~np.isfinite(positions).all(axis=-1)
        positions[lost] = np.nan
        quality = np.stack([q[ii, jj] for q in qualities])
        ids = ii * active.shape[1] + jj + 1
        kind = {"lines": "symmetry", "hessian": "peak-sharpness", "snake": "snake"}[self.refiner]
        meta = {"tracker": "grid", "refiner": self.refiner, "pitch_px": geometry.pitch,
                "line_width_px": geometry.line_width, "dark_lines": geometry.dark_lines,
                **({"line_shape": self.line_shape} if self.refiner == "lines" else {}),
                "col_step_px": tuple(geometry.col_step), "row_step_px": tuple(geometry.row_step)}
        return Tracks(ids=ids, reference=positions[0], positions=positions, lost=lost, quality=quality,
                      grid_index=np.stack([ii, jj], axis=1), quality_kind=kind, meta=meta)
