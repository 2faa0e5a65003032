"""The speckle tracker: subset-based digital image correlation (DIC) on a lattice of points.

Points sit every ``spacing`` px in the region of interest, where the speckle is (``_pattern_mask``:
holes, background beyond the edges and glare are left out, and a subset must lie wholly on the
pattern, whose texture-less edges are read at the pixel scale: ``textured_material``, so that a
kept subset lies on material to about half a pixel). Each frame's global affine motion is estimated first (``_coarse``: correlation of the
whole images over a tenth of their size, then ECC), so a frame may jump by far more than a
subset; each point starts IC-GN (see ``_dic``) from that map plus its own residual from the
previous frames extrapolated at constant velocity (with ``reference="previous"`` the map from
the previous frame, estimated between the two, moves each subset from where it was last seen);
points without a usable start (the first deformed frame, or after a failure) get an integer
guess by normalised cross-correlation within ``search`` px of it first. A point is lost in a
frame, with its reason in ``meta["lost_reasons"]`` (see ``_lost``), when IC-GN does not converge,
the subset leaves the image or meets saturated pixels, the ZNCC falls under ``min_zncc``, the
match lies farther from its prediction than the search reaches (a slip), or its motion is not
supported by its neighbours' (``_support``: more than ``max_disagreement`` px, or six robust
standard deviations, from what they predict); with ``reference="first"`` it is tried again
(from its neighbours' motion) in the next frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from . import _lost as lost_codes
from ._coarse import CoarseMotion, speckle_motion
from ._dic import icgn, reference_subsets
from ._dic_search import integer_search
from ._errors import OptionError, RoiError
from ._grid_topology import fill_field
from ._images import as_stack, roi_mask
from ._interp import spline_image
from ._pattern_mask import material_outline, pattern_mask, saturated, textured_material
from ._support import unsupported
from ._tracks import Tracks


@dataclass(frozen=True)
class SpeckleTracker:
    """Subset DIC: affine subsets, ZNSSD criterion, IC-GN, B-spline interpolation.

    Attributes:
        spacing: distance between correlation points (px).
        subset: subset side (px, odd; 21-41 is usual).
        search: integer search half-range (px) around the predicted motion.
        order: B-spline order of the target interpolation (3 bicubic, 5 quintic).
        smoothing: Gaussian pre-smoothing of all images (px, 0 = none); 0.8 removes most of the
            interpolation bias (Pan et al. 2013) at almost no cost in noise.
        reference: "first" (every frame against frame 0; no drift) or "previous" (frame k
            against frame k-1; follows larger deformations, drift accumulates, a lost point
            stays lost).
        min_zncc: correlation under which a point is lost.
        max_disagreement: a match farther than this (px) from the motion its lattice neighbours
            predict (and than six robust standard deviations of those distances) is lost.
        max_iterations, tolerance: IC-GN stopping rule (tolerance in px at the subset edge).
        subset_in_roi: keep only points whose whole subset lies in the ROI (else the centre).
        find_pattern: track only where the speckle is (holes, background, glare left out).
        coarse: estimate each frame's global motion first (jumps of up to a tenth of the image).
    """

    spacing: float = 10.0
    subset: int = 21
    search: int = 10
    order: int = 3
    smoothing: float = 0.8
    reference: str = "first"
    min_zncc: float = 0.8
    max_disagreement: float = 0.1
    max_iterations: int = 40
    tolerance: float = 1e-3
    subset_in_roi: bool = True
    find_pattern: bool = True
    coarse: bool = True

    def points(self, mask: np.ndarray, material: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Correlation points in ``mask`` (rows, cols): xy (n, 2) integer pixels, (row, col) (n, 2);
        the lattice spans ``mask``, and a point's subset (``subset_in_roi``; else the point) lies
        wholly in ``material`` (rows, cols) bool (None: ``mask``)."""
        radius = self.subset // 2
        margin = radius + 2
        rows, cols = np.nonzero(mask)
        h, w = mask.shape
        x0, y0 = max(cols.min() + radius, margin), max(rows.min() + radius, margin)
        xs = np.arange(x0, min(cols.max() - radius, w - 1 - margin) + 1, self.spacing)
        ys = np.arange(y0, min(rows.max() - radius, h - 1 - margin) + 1, self.spacing)
        xx, yy = np.meshgrid(np.rint(xs), np.rint(ys))
        jj, ii = np.meshgrid(np.arange(len(xs)), np.arange(len(ys)))
        xy = np.stack([xx.ravel(), yy.ravel()], axis=1)
        index = np.stack([ii.ravel(), jj.ravel()], axis=1)
        keep = ((xy[:, 0] >= margin) & (xy[:, 1] >= margin)
                & (xy[:, 0] < w - margin) & (xy[:, 1] < h - margin))
        material = mask if material is None else material
        if self.subset_in_roi:
            inside = ndimage.binary_erosion(material, np.ones((self.subset, self.subset)), border_value=0)
        else:
            inside = material
        ok = np.zeros(len(xy), bool)
        ok[keep] = inside[xy[keep, 1].astype(int), xy[keep, 0].astype(int)]
        if not ok.any():
            raise RoiError(f"no correlation point fits in the ROI with subset {self.subset} px; "
                           "enlarge the ROI or use a smaller subset")
        return xy[ok], index[ok]

    def track(self, images, roi=None) -> Tracks:
        """Track a lattice of points in the ROI through ``images``; quality is the ZNCC (-1..1).

        ``meta`` holds ``lost_reasons`` (n_frames, n) int8 and ``lost_reason_names`` (see
        ``tracking._lost``), ``excluded`` ({reason: lattice points in the ROI not made points}),
        ``pattern_mask``, ``material_mask`` (the mask less its texture-less edges at the pixel
        scale: every point's whole subset lies in it), ``outline`` ({"outer": (k, 2), "holes": [(m, 2), ...]} px) and
        ``coarse_motion`` (per frame: the global affine (2, 3) and whether the data supported it).
        """
        if self.subset < 5 or self.subset % 2 == 0:
            raise OptionError(f"subset must be an odd number of pixels >= 5, got {self.subset}")
        if self.reference not in ("first", "previous"):
            raise OptionError(f"reference must be 'first' or 'previous', got {self.reference!r}")
        raw = as_stack(images)
        stack = raw
        if self.smoothing > 0:
            stack = np.stack([ndimage.gaussian_filter(im, self.smoothing) for im in raw])
        roi = roi_mask(roi, stack.shape[1:])
        mask = pattern_mask(raw[0], self.subset, roi) if self.find_pattern else roi
        material = textured_material(raw[0], mask, self.subset, roi) if self.find_pattern else roi
        xy, index = self.points(mask, material)
        excluded = {}
        if self.find_pattern:
            lattice_in_roi, on_pattern = len(self.points(roi)[0]), len(self.points(mask)[0])
            excluded = lost_codes.reason_counts(np.r_[np.full(max(lattice_in_roi - on_pattern, 0), lost_codes.OFF_PATTERN),
                                                      np.full(max(on_pattern - len(xy), 0), lost_codes.SUBSET_EDGE)])
        n = len(xy)
        positions = np.full((len(stack), n, 2), np.nan)
        quality = np.zeros((len(stack), n))
        codes = np.zeros((len(stack), n), np.int8)
        positions[0], quality[0] = xy, 1.0
        lattice = (index[:, 0].max() + 1, index[:, 1].max() + 1)
        radius = self.subset // 2
        reference = spline_image(stack[0], self.order)
        first_subsets = reference_subsets(reference, reference.lattice_gradient(), xy, radius)
        motions = [CoarseMotion.identity()]
        history = [np.zeros((n, 6))]          # p of every frame against frame 0 ("first"), less its map's
        residual = np.zeros((n, 6))           # last frame-to-frame p less its map's ("previous")
        alive = np.ones(n, bool)
        before = reference
        rows, cols = np.nonzero(mask)
        search = 0.1 * max(np.ptp(rows) + 1, np.ptp(cols) + 1)
        for k in range(1, len(stack)):
            motion = self._motion(stack, k, motions, search)
            target = spline_image(stack[k], self.order)
            if self.reference == "previous" and k > 1:
                alive &= ~np.isnan(positions[k - 1]).any(axis=1)
                last = np.where(alive[:, None], positions[k - 1], xy)
                centres = np.rint(last)
                offset = last - centres
                subsets = reference_subsets(before, before.lattice_gradient(), centres, radius)
                step = motion.since(motions[-1])
                base = stack[k - 1]
            else:
                centres, offset, subsets, step, base = xy, np.zeros((n, 2)), first_subsets, motion, stack[0]
                residual = self._start(history, index, lattice)
            start = _map_parameters(step, centres) + np.nan_to_num(residual)
            p, zncc, ok = self._match(base, stack[k], target, subsets, centres, start, k == 1)
            ok &= alive
            origin = centres + offset
            codes[k] = self._reasons(raw[k], origin, p, start, ok, zncc, alive, index)
            ok &= codes[k] == lost_codes.MEASURED
            positions[k] = np.where(ok[:, None], _moved(origin, centres, p), np.nan)
            quality[k] = zncc
            history.append(np.where(ok[:, None], p - _map_parameters(motion, xy), np.nan))
            residual = np.where(ok[:, None], p - _map_parameters(step, centres), np.nan)
            motions.append(motion)
            before = target
        lost = ~np.isfinite(positions).all(axis=-1)
        meta = {"tracker": "speckle", "subset_px": self.subset, "spacing_px": self.spacing,
                "reference": self.reference, "spline_order": self.order,
                "lost_reasons": codes, "lost_reason_names": dict(lost_codes.LOST_REASONS),
                "excluded": excluded, "pattern_mask": mask, "material_mask": material,
                "outline": material_outline(mask, min_hole_area=float(self.subset) ** 2),
                "coarse_motion": [{"affine": np.hstack([m.linear, m.offset[:, None]]), "supported": m.supported}
                                  for m in motions]}
        return Tracks(ids=index[:, 0] * lattice[1] + index[:, 1] + 1, reference=xy, positions=positions,
                      lost=lost, quality=quality, grid_index=index, quality_kind="zncc", meta=meta)

    def _motion(self, stack, k, motions, search) -> CoarseMotion:
        """Frame k's global map from frame 0 (against frame k - 1 with ``reference="previous"``)."""
        prior = motions[-1].extrapolated(motions[-2]) if len(motions) >= 2 else motions[-1]
        if not self.coarse:
            return prior
        # the search covers both a constant velocity and a stop (a jump may change direction)
        centre = 0.5 * np.array(stack.shape[:0:-1], dtype=np.float64)
        search = search + float(np.linalg.norm(prior.apply(centre) - motions[-1].apply(centre)))
        if self.reference == "previous" and k > 1:
            step = speckle_motion(stack[k - 1], stack[k], prior.since(motions[-1]), search)
            return motions[-1].then(step)
        return speckle_motion(stack[0], stack[k], prior, search)

    def _reasons(self, image, origin, p, start, ok, zncc, alive, index) -> np.ndarray:
        """Lost-reason codes (n,) int8 of one frame's matches ``p`` (n, 6) of the points at
        ``origin`` (n, 2) px in the frame matched from, IC-GN started from ``start`` (n, 6)."""
        radius = self.subset // 2
        centres = np.rint(origin)
        moved = _moved(origin, centres, p)
        rows, cols = image.shape
        x, y = np.nan_to_num(moved, nan=-1e9).T
        outside = (x < radius) | (y < radius) | (x > cols - 1 - radius) | (y > rows - 1 - radius)
        codes = np.zeros(len(moved), np.int8)
        codes = lost_codes.first_reason(codes, ~alive, lost_codes.NOT_SEEN)
        codes = lost_codes.first_reason(codes, outside, lost_codes.LEFT_IMAGE)
        glare = saturated(image)
        if glare.any():
            grown = ndimage.binary_dilation(glare, np.ones((self.subset, self.subset), bool))
            inside = ~outside
            hit = np.zeros(len(moved), bool)
            hit[inside] = grown[np.rint(y[inside]).astype(int), np.rint(x[inside]).astype(int)]
            codes = lost_codes.first_reason(codes, hit, lost_codes.SATURATED)
        codes = lost_codes.first_reason(codes, ~ok | (zncc < self.min_zncc), lost_codes.REJECTED)
        # a match farther from its start than the search reaches (or half a subset) did not come
        # from the search: IC-GN wandered off
        reach = max(radius, self.search) + 1.0
        slipped = np.abs(moved - _moved(origin, centres, start)).max(axis=1) > reach
        codes = lost_codes.first_reason(codes, slipped, lost_codes.SLIP)
        measured = codes == lost_codes.MEASURED
        gradient = p[:, [1, 2, 4, 5]].reshape(-1, 2, 2)
        alone = unsupported(index, origin, moved - origin, gradient, measured, self.max_disagreement)
        return lost_codes.first_reason(codes, alone, lost_codes.JUMP)

    def _start(self, history, index, lattice):
        """Constant-velocity prediction of p per point; lost points take their neighbours'."""
        last = history[-1]
        if len(history) >= 2:
            before = history[-2]
            guess = np.where(np.isfinite(before), 2 * last - before, last)
        else:
            guess = last
        valid = np.isfinite(guess).all(axis=1)
        if valid.all() or not valid.any():
            return np.nan_to_num(guess)
        field = np.zeros(lattice + (6,))
        known = np.zeros(lattice, bool)
        field[index[:, 0], index[:, 1]] = np.nan_to_num(guess)
        known[index[:, 0], index[:, 1]] = valid
        filled = fill_field(field, known)
        return filled[index[:, 0], index[:, 1]]

    def _match(self, base, image, target, subsets, centres, start, first):
        """IC-GN from ``start``; where that fails (or in the first frame), integer search first."""
        radius = self.subset // 2
        p = start.copy()
        if first:
            shift, _ = integer_search(base, image, centres, radius, start[:, [0, 3]], self.search)
            usable = np.isfinite(shift).all(axis=1)
            p[usable, 0], p[usable, 3] = shift[usable, 0], shift[usable, 1]
        match = icgn(target, subsets, p, self.max_iterations, self.tolerance)
        ok = match.converged & (match.zncc >= self.min_zncc)
        if not first and not ok.all():
            retry = np.nonzero(~ok)[0]
            shift, _ = integer_search(base, image, centres[retry], radius,
                                      start[retry][:, [0, 3]], self.search)
            usable = np.isfinite(shift).all(axis=1)
            again = retry[usable]
            p_retry = start[again].copy()
            p_retry[:, 0], p_retry[:, 3] = shift[usable, 0], shift[usable, 1]
            second = icgn(target, subsets.take(again), p_retry, self.max_iterations, self.tolerance)
            better = second.converged & (second.zncc >= self.min_zncc)
            match.p[again[better]] = second.p[better]
            match.zncc[again[better]] = second.zncc[better]
            ok[again[better]] = True
        return match.p, match.zncc, ok


def _moved(origin: np.ndarray, centres: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Where the warp ``p`` (n, 6) of subsets centred at ``centres`` (n, 2) takes the points
    ``origin`` (n, 2) (a tracked point may sit off its subset's integer centre), (n, 2) px."""
    offset = origin - centres
    gradient = p[:, [1, 2, 4, 5]].reshape(-1, 2, 2)
    return centres + offset + p[:, [0, 3]] + np.einsum("nij,nj->ni", gradient, offset)


def _map_parameters(motion: CoarseMotion, xy: np.ndarray) -> np.ndarray:
    """IC-GN parameters (n, 6) = (u, ux, uy, v, vx, vy) of an affine map at points (n, 2)."""
    u = motion.apply(xy) - xy
    g = motion.linear - np.eye(2)
    return np.column_stack([u[:, 0], np.full(len(xy), g[0, 0]), np.full(len(xy), g[0, 1]),
                            u[:, 1], np.full(len(xy), g[1, 0]), np.full(len(xy), g[1, 1])])
