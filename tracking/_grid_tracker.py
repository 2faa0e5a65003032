"""The grid tracker: crossings of a painted grid, found with snakes and refined to sub-pixels.

Reference frame: the lattice (pitch, orientation, polarity, line width) comes from the image
spectrum; the pattern's extent (where the grid's texture is: not a hole, not the background
beyond an edge, not glare) from ``_pattern_mask``; crossing candidates from the smoothed ink on
that extent, their (row, column) from growing the lattice from the pattern's most interior
point; snakes on the row and column lines give the crossings, which a refiner (default:
symmetric line fitting) brings to sub-pixel accuracy.

Later frames, coarse to fine: the frame's global affine motion is estimated first (``_coarse``:
the lattice from the spectrum, the translation from the silhouette, which is not periodic), so a
sheet may move several pitches between frames; each crossing is predicted by that map plus its
own residual from the previous frames (constant velocity), corrected ring by ring from detected
crossings (neighbour to neighbour the motion differs by strain x pitch), then snakes and the
refiner run again. Where the view holds nothing but grid, the global motion is the previous
frames' extrapolated (a motion of half a pitch or more is then not observable).

A crossing is lost in a frame, with its reason in ``meta["lost_reasons"]`` (see ``_lost``), when
the refiner rejects it, when saturated pixels lie on it, when its motion disagrees with its
neighbours' by more than ``max_jump`` pitches, or when it is more than half a pitch from the
frame's supported global prediction (a lattice slip); it is looked for again in the next frame.
A supported global map under which fewer than half the crossings in view are measured is not
borne out: the frame is measured again from the temporal prior, and if that measures no more
than half either, every crossing of the frame is lost as a slip (``_borne_out``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np
from scipy import ndimage

from . import _lost as lost_codes
from ._coarse import CoarseMotion, carry, grid_motion, silhouette
from ._crossings import CrossingGuess, GridFrame, Refined
from ._errors import GridNotFoundError, OptionError, TrackingError
from ._grid_motion import affine_fit, jumps, predict, propagate
from ._grid_topology import crossing_candidates, fill_positions, interior_gaps, label_grid, lattice_spacing
from ._images import as_stack, inside_mask, roi_mask
from ._lattice import GridGeometry, grid_geometry, ink_image
from ._pattern_mask import material_outline, pattern_mask, saturated
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
        find_pattern: track only where the grid is seen (holes, background, glare left out);
            False: every crossing in the ROI.
        coarse: estimate each frame's global motion first (large motion between frames).
    """

    refiner: str = "lines"
    pitch_range: tuple[float, float] = (4.0, 80.0)
    dark_lines: bool | None = None
    snake: SnakeOptions = field(default_factory=SnakeOptions)
    max_jump: float = 0.3
    min_quality: float | None = None
    line_shape: str = "adaptive"
    find_pattern: bool = True
    coarse: bool = True

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
                Crossings of the first image inside it (and on the pattern) are tracked.

        Returns:
            Tracks with ``grid_index`` (row, col), ``quality_kind`` the refiner's score, and in
            ``meta``: ``lost_reasons`` (n_frames, n) int8 codes and ``lost_reason_names``
            (see ``tracking._lost``), ``excluded`` ({reason: lattice nodes in the ROI never
            made points}), ``pattern_mask`` (rows, cols) bool, ``outline`` ({"outer": (k, 2),
            "holes": [(m, 2), ...]} px, the material's polygon and its holes) and
            ``coarse_motion`` (per frame: the global affine (2, 3) and whether the data
            supported it).
        """
        stack = as_stack(images)
        roi = roi_mask(roi, stack.shape[1:])
        refiner = self._refiner()
        geometry = grid_geometry(stack[0], roi, self.pitch_range, self.dark_lines)
        material = roi
        if self.find_pattern:
            material = self._material(stack[0], roi, geometry)
            # the lattice again on the grid alone (an edge or the background beside the sheet
            # pulls the whole view's peaks by a few per cent); its mask again if that moved it
            for _ in range(2):
                found = grid_geometry(stack[0], material, self.pitch_range, self.dark_lines)
                moved = abs(found.pitch / geometry.pitch - 1.0) > 0.01
                geometry = found
                if not moved:
                    break
                material = self._material(stack[0], roi, geometry)
        nodes, quality, excluded = self._reference(stack[0], material, roi, geometry, refiner)
        active = np.isfinite(nodes[..., 0])
        history, qualities = [nodes], [quality]
        reasons = [np.zeros(active.shape, np.int8)]
        features = silhouette(stack[0], geometry.pitch, saturated(stack[0]))
        # an edge between material and background, blurred at a pitch, has a gradient of about
        # its contrast / (2.5 pitch); a tenth of the pattern's spread per pitch marks one
        min_contrast = 0.1 * float(np.std(stack[0][material])) / geometry.pitch
        motions = [CoarseMotion.identity()]
        for image in stack[1:]:
            fitted = [affine_fit(nodes, h, active) for h in history]
            prior = fitted[-1].extrapolated(fitted[-2]) if len(fitted) >= 2 else fitted[-1]
            # the frame's lattice is read where the material is expected: the reference's mask
            # carried by the prior, less half a pitch (the prior is not exact)
            expected = ndimage.binary_erosion(_moved(material, prior), iterations=max(1, int(0.5 * geometry.pitch)))
            motion = grid_motion(features, image, geometry, prior, min_contrast, saturated(image), expected) \
                if self.coarse else prior
            measure = lambda m: self._frame(image, history, fitted, m, active, geometry, refiner,  # noqa: E731
                                            material, roi)
            # a map the crossings refute gives way to the prior under the frame's own lattice
            fallback = carry(prior, motion.linear, image.shape) if self.coarse else prior
            motion, (positions, quality, reason) = _borne_out(motion, fallback, measure, active)
            history.append(positions)
            qualities.append(quality)
            reasons.append(reason)
            motions.append(motion)
        meta = {"excluded": excluded, "pattern_mask": material,
                "outline": material_outline(material, min_hole_area=geometry.pitch ** 2),
                "coarse_motion": [{"affine": np.hstack([m.linear, m.offset[:, None]]), "supported": m.supported}
                                  for m in motions]}
        return self._tracks(history, qualities, reasons, active, geometry, meta)

    def _material(self, image, roi, geometry: GridGeometry) -> np.ndarray:
        """The grid's pattern mask in ``roi`` under the lattice ``geometry`` (the mask stage)."""
        waves = np.linalg.inv(np.stack([geometry.col_step, geometry.row_step], axis=1))
        try:
            material = pattern_mask(image, geometry.pitch, roi, waves)
        except TrackingError as e:
            raise GridNotFoundError(f"grid not found at the mask stage: {e}", "mask") from e
        if np.count_nonzero(material) < 4 * geometry.pitch ** 2:
            raise GridNotFoundError(
                f"grid not found at the mask stage: the grid's texture (pitch {geometry.pitch:.1f} px) covers "
                f"{np.count_nonzero(material)} px of the region of interest, under 4 cells; try a region of "
                "interest on the grid (--roi), the grid's pitch range if that pitch is wrong "
                "(GridTracker.pitch_range; --option 'pitch_range=(LO,HI)'), or find_pattern=False "
                "(--option find_pattern=False) to measure every crossing of the ROI", "mask")
        return material

    def _reference(self, image, material, roi, geometry: GridGeometry, refiner):
        ink = ink_image(image, geometry, _ink_mask(material, roi))
        candidates = crossing_candidates(ink, geometry.pitch, material, (geometry.col_step, geometry.row_step),
                                         _inner(material, roi, geometry.pitch))
        # grow the lattice from the pattern's most interior point (not the ROI's centre: a hole)
        depth = ndimage.distance_transform_edt(np.pad(material, 1))[1:-1, 1:-1]
        row, col = np.unravel_index(int(np.argmax(depth)), depth.shape)
        if len(candidates) < 4:
            raise self._no_crossings(0, len(candidates), 0, geometry)
        nodes = label_grid(candidates, geometry, (col, row))
        valid = np.isfinite(nodes[..., 0])
        filled = fill_positions(nodes, valid)
        on_pattern = inside_mask(material, filled.reshape(-1, 2)).reshape(valid.shape)
        in_roi = inside_mask(roi, filled.reshape(-1, 2)).reshape(valid.shape)
        gaps = interior_gaps(valid) & on_pattern
        nodes = np.where(gaps[..., None], filled, nodes)
        frame = GridFrame(image, ink, geometry.line_width, geometry.pitch)
        positions, quality, ok = self._measure(frame, nodes, valid | gaps, geometry, refiner)
        ok &= inside_mask(material, np.nan_to_num(positions, nan=-1.0).reshape(-1, 2)).reshape(ok.shape)
        if np.count_nonzero(ok) < 4:
            raise self._no_crossings(np.count_nonzero(ok), len(candidates), np.count_nonzero(valid), geometry)
        positions[~ok] = np.nan
        glare = _near(saturated(image), filled, 0.5 * geometry.pitch)
        excluded = lost_codes.reason_counts(np.select(
            [ok, ~in_roi, ~on_pattern & glare, ~on_pattern, ~(valid | gaps), True],
            [lost_codes.MEASURED, lost_codes.MEASURED, lost_codes.SATURATED, lost_codes.OFF_PATTERN,
             lost_codes.NOT_SEEN, lost_codes.REJECTED]))
        return positions, quality, excluded

    def _no_crossings(self, measured: int, found: int, labelled: int, geometry: GridGeometry) -> GridNotFoundError:
        """The crossings stage's error: what was found, and what to try."""
        polarity = "dark" if geometry.dark_lines else "light"
        other = "dark_lines=False" if geometry.dark_lines else "dark_lines=True"
        hints = [f"the other polarity ({other}; --option {other})" if self.dark_lines is None else
                 "the polarity you set (dark_lines) if it is not the grid's"]
        hints += ["the grid's pitch range if that pitch is wrong (GridTracker.pitch_range; --option "
                  "'pitch_range=(LO,HI)' in px)", "a region of interest on the grid alone (--roi)"]
        if measured < labelled:
            hints.append(f"a lower min_quality (--min-quality; the refiner's is {self._refiner().min_quality:g})"
                         if hasattr(self._refiner(), "min_quality") else "another refiner (--refiner)")
        return GridNotFoundError(
            f"grid not found at the crossings stage: only {measured} grid crossings could be measured in the "
            f"reference image ({found} candidates found, {labelled} labelled on the lattice of pitch "
            f"{geometry.pitch:.1f} px with {polarity} lines {geometry.line_width:.1f} px wide); try " + ", ".join(hints),
            "crossings")

    def _frame(self, image, history, fitted, motion: CoarseMotion, active, geometry: GridGeometry, refiner,
               material, roi):
        reference = history[0]
        # each crossing's own deviation from its frame's affine motion, extrapolated in time
        residual = [h - f.apply(reference) + reference for h, f in zip(history, fitted)]
        predicted = motion.apply(reference) + predict(residual, active) - reference
        moved, moved_roi = _moved(material, motion), _moved(roi, motion)
        ink = ink_image(image, geometry, _ink_mask(moved, moved_roi))
        candidates = crossing_candidates(ink, geometry.pitch, None,
                                         (motion.linear @ geometry.col_step, motion.linear @ geometry.row_step),
                                         _inner(moved, moved_roi, geometry.pitch) | ~moved_roi)
        coarse, _ = propagate(predicted, active, candidates, radius=0.3 * geometry.pitch)
        frame = GridFrame(image, ink, geometry.line_width, geometry.pitch)
        positions, quality, ok = self._measure(frame, coarse, active, geometry, refiner)
        reason = np.zeros(active.shape, np.int8)
        rows, cols = image.shape
        x, y = np.nan_to_num(predicted, nan=-1e9)[..., 0], np.nan_to_num(predicted, nan=-1e9)[..., 1]
        outside = (x < 0) | (y < 0) | (x > cols - 1) | (y > rows - 1)
        reason = lost_codes.first_reason(reason, active & ~ok & outside, lost_codes.LEFT_IMAGE)
        glare = _near(saturated(image), np.where(np.isfinite(positions), positions, coarse), 0.5 * geometry.pitch)
        reason = lost_codes.first_reason(reason, active & glare, lost_codes.SATURATED)
        reason = lost_codes.first_reason(reason, active & ~ok, lost_codes.REJECTED)
        ok &= reason == lost_codes.MEASURED
        if motion.supported:
            slip = np.linalg.norm(np.nan_to_num(positions - predicted, nan=0.0), axis=-1) > 0.5 * geometry.pitch
            reason = lost_codes.first_reason(reason, ok & slip, lost_codes.SLIP)
            ok &= ~slip
        last = history[-1]
        step = np.where(np.isfinite(last), positions - last, positions - predicted)
        jumped = jumps(step, ok, self.max_jump * geometry.pitch)
        reason = lost_codes.first_reason(reason, jumped, lost_codes.JUMP)
        ok &= ~jumped
        positions[~ok] = np.nan
        return positions, quality, np.where(active, reason, 0).astype(np.int8)

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

    def _tracks(self, history, qualities, reasons, active, geometry: GridGeometry, extra: dict) -> Tracks:
        ii, jj = np.nonzero(active)
        positions = np.stack([h[ii, jj] for h in history])
        lost = ~np.isfinite(positions).all(axis=-1)
        positions[lost] = np.nan
        quality = np.stack([q[ii, jj] for q in qualities])
        codes = np.stack([r[ii, jj] for r in reasons])
        codes = np.where(lost & (codes == lost_codes.MEASURED), lost_codes.NOT_SEEN, codes).astype(np.int8)
        ids = ii * active.shape[1] + jj + 1
        kind = {"lines": "symmetry", "hessian": "peak-sharpness", "snake": "snake"}[self.refiner]
        meta = {"tracker": "grid", "refiner": self.refiner, "pitch_px": geometry.pitch,
                "line_width_px": geometry.line_width, "dark_lines": geometry.dark_lines,
                **({"line_shape": self.line_shape} if self.refiner == "lines" else {}),
                "col_step_px": tuple(geometry.col_step), "row_step_px": tuple(geometry.row_step),
                "lost_reasons": codes, "lost_reason_names": dict(lost_codes.LOST_REASONS), **extra}
        return Tracks(ids=ids, reference=positions[0], positions=positions, lost=lost, quality=quality,
                      grid_index=np.stack([ii, jj], axis=1), quality_kind=kind, meta=meta)


def _borne_out(motion: CoarseMotion, prior: CoarseMotion, measure, active: np.ndarray):
    """The frame's map and its measurement ``measure(map)`` -> (positions, quality, reason).

    A supported map the crossings do not bear out (see :func:`_refuted`; e.g. a silhouette
    translation fixed by something that is not on the material) gives way to the temporal
    ``prior`` when that measures more crossings; if the crossings bear out neither, none is
    written: all are lost as slips (a match the data do not support is never a measurement).
    """
    positions, quality, reason = measure(motion)
    if not (motion.supported and _refuted(reason, active)):
        return motion, (positions, quality, reason)
    retry = measure(prior)
    if _measured(retry[2], active) > _measured(reason, active):
        motion, (positions, quality, reason) = prior, retry
    if _refuted(reason, active):
        reason = lost_codes.first_reason(reason, active, lost_codes.SLIP)
        positions = np.where((reason == lost_codes.MEASURED)[..., None], positions, np.nan)
    return motion, (positions, quality, reason)


def _measured(reason: np.ndarray, active: np.ndarray) -> int:
    return int(np.count_nonzero(active & (reason == lost_codes.MEASURED)))


def _refuted(reason: np.ndarray, active: np.ndarray) -> bool:
    """True when fewer than half the active crossings still in view (not left the image, not
    under glare) were measured in a frame: its global map is not borne out by the crossings."""
    in_view = active & (reason != lost_codes.LEFT_IMAGE) & (reason != lost_codes.SATURATED)
    return _measured(reason, active) < 0.5 * np.count_nonzero(in_view)


def _ink_mask(material: np.ndarray, roi: np.ndarray) -> np.ndarray | None:
    """Where the ink's local means are taken: all but what the pattern mask left out of the ROI
    (holes, background); None when that is nothing (the ink is then as without a mask)."""
    mask = material | ~roi
    return None if mask.all() else mask


def _inner(material: np.ndarray, roi: np.ndarray, pitch: float) -> np.ndarray:
    """The material less a band of a quarter pitch along its edges inside the ROI (a hole's, the
    sheet's; not the ROI's own border): where crossing candidates set the strength they are
    judged by, because at the material's edge the ink's local normalisation sees half a
    neighbourhood and can peak far above any crossing's ink."""
    # the mask's own fall within half a pitch of the ROI's border (or the image's) is no edge
    inside = ndimage.distance_transform_edt(np.pad(roi, 1))[1:-1, 1:-1] > 0.5 * pitch
    off = ~material & inside
    if not off.any():
        return material
    return material & (ndimage.distance_transform_edt(~off) > 0.25 * pitch)


def _moved(mask: np.ndarray, motion: CoarseMotion) -> np.ndarray:
    """The reference ``mask`` carried into a frame by its global motion (nearest pixel)."""
    matrix = np.hstack([motion.linear, motion.offset[:, None]])
    moved = cv2.warpAffine(mask.astype(np.uint8), matrix, mask.shape[::-1], flags=cv2.INTER_NEAREST)
    return moved.astype(bool)


def _near(mask: np.ndarray, nodes: np.ndarray, radius: float) -> np.ndarray:
    """(R, C) bool: nodes (R, C, 2) with a True pixel of ``mask`` within ``radius`` px."""
    if not mask.any():
        return np.zeros(nodes.shape[:2], bool)
    grown = ndimage.binary_dilation(mask, iterations=max(1, int(round(radius))))
    xy = np.nan_to_num(nodes, nan=-1.0).reshape(-1, 2)
    return inside_mask(grown, xy).reshape(nodes.shape[:2]) & np.isfinite(nodes[..., 0])
