"""Grid crossings as a (rows, cols) lattice: candidate detection, labelling, filling gaps.

Node arrays are (R, C, 2) float with NaN where the lattice has no point; row index i grows with
y and column index j with x.
"""

from __future__ import annotations

from collections import deque

import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

from ._errors import GridNotFoundError, TrackingError
from ._lattice import GridGeometry

NEIGHBOURS = ((0, 1), (0, -1), (1, 0), (-1, 0))


def crossing_candidates(ink: np.ndarray, pitch: float, mask: np.ndarray | None = None,
                        steps: tuple[np.ndarray, np.ndarray] | None = None,
                        inner: np.ndarray | None = None) -> np.ndarray:
    """Local maxima of the ink smoothed at a quarter pitch (where two lines cross), (m, 2) xy.

    Smoothing at pitch/4 leaves one maximum per crossing (more ink around a crossing than along a
    line), a saddle between crossings and minima in the cells. With the lattice ``steps``
    (col_step, row_step) the maxima are those of a crossing's template instead: the smoothed
    ink at the point plus its mean at the four arms' midpoints (half a step away) less its mean
    at the four cell centres around it. A crossing scores high on all of it; a bright patch of
    ink that is no crossing (what is left of an edge's step, a blemish, the border of the
    mask) has no arms and cells around it and scores low, so it no longer sets the strength
    that faint real crossings are judged against.

    A maximum is kept when it reaches 0.35 of the 90th percentile of the maxima in ``inner``
    (default: all), e.g. the material away from its edges, where the ink's local normalisation
    sees half a neighbourhood and can peak far above any crossing, and where the template's
    samples all lie in the image.
    """
    smooth = ndimage.gaussian_filter(ink, 0.25 * pitch, mode="nearest")
    judged = np.ones(ink.shape, bool) if inner is None else np.asarray(inner, bool)
    if steps is not None:
        a, b = 0.5 * np.asarray(steps[0], float), 0.5 * np.asarray(steps[1], float)

        def at(d):
            return ndimage.shift(smooth, (-d[1], -d[0]), order=1, mode="nearest")

        arms = 0.25 * (at(a) + at(-a) + at(b) + at(-b))
        cells = 0.25 * (at(a + b) + at(a - b) + at(-a + b) + at(-a - b))
        smooth = smooth + arms - cells
        # the template is judged only where all its samples lie in the image (beyond its border
        # the shifted samples repeat the border's values), or, the laxer of the two, on the mask
        # too (at its edge a sample off the material reads an ink of 0)
        offsets = (a, -a, b, -b, a + b, a - b, -a + b, -a - b)
        judged = judged & _all_shifted(np.ones(ink.shape, bool), offsets)
        if mask is not None:
            on_material = judged & _all_shifted(np.asarray(mask, bool), offsets)
    size = max(3, int(0.6 * pitch) | 1)
    peaks = (smooth == ndimage.maximum_filter(smooth, size=size, mode="nearest"))
    if mask is not None:
        peaks &= mask
    rows, cols = np.nonzero(peaks)
    if rows.size == 0:
        return np.zeros((0, 2))
    values = smooth[rows, cols]

    def level(where):
        typical = values[where[rows, cols]]
        return np.percentile(typical if typical.size else values, 90)

    floor = level(judged)
    if steps is not None and mask is not None and np.any(on_material[rows, cols]):
        floor = min(floor, level(on_material))
    strong = values > 0.35 * floor
    return np.stack([cols[strong], rows[strong]], axis=1).astype(np.float64)


def _all_shifted(mask: np.ndarray, offsets) -> np.ndarray:
    """(rows, cols) bool: pixels p with p + d in ``mask`` for every offset d (x, y) of ``offsets``."""
    out = np.ones(mask.shape, bool)
    for d in offsets:
        out &= ndimage.shift(mask.astype(np.float64), (-d[1], -d[0]), order=0, cval=0.0) > 0.5
    return out


def label_grid(candidates: np.ndarray, geometry: GridGeometry, seed_xy) -> np.ndarray:
    """Give every candidate crossing its (row, col) by growing the lattice from ``seed_xy``.

    A neighbour is predicted from the node by the local lattice step (measured from the node's
    own labelled neighbours where they exist) and accepted when a candidate lies within 0.3 of a
    step of the prediction. Returns nodes (R, C, 2), NaN where no candidate was found.
    """
    if len(candidates) < 4:
        raise GridNotFoundError(f"grid not found at the crossings stage: only {len(candidates)} grid crossings "
                                "found, at least 4 are needed", "crossings")
    tree = cKDTree(candidates)
    start = int(tree.query(np.asarray(seed_xy, dtype=np.float64))[1])
    label = {start: (0, 0)}
    where = {(0, 0): start}
    queue = deque([start])
    steps = {(0, 1): geometry.col_step, (1, 0): geometry.row_step}
    while queue:
        node = queue.popleft()
        i, j = label[node]
        here = candidates[node]
        for di, dj in NEIGHBOURS:
            target = (i + di, j + dj)
            if target in where:
                continue
            step = _local_step(candidates, where, i, j, abs(di), abs(dj), steps[(abs(di), abs(dj))])
            guess = here + (di + dj) * step
            distance, found = tree.query(guess)
            if distance > 0.3 * np.linalg.norm(step) or found in label:
                continue
            label[found] = target
            where[target] = found
            queue.append(found)
    keys = np.array(list(where.keys()))
    i0, j0 = keys.min(axis=0)
    shape = tuple(keys.max(axis=0) - (i0, j0) + 1)
    nodes = np.full(shape + (2,), np.nan)
    for (i, j), k in where.items():
        nodes[i - i0, j - j0] = candidates[k]
    return nodes


def _local_step(candidates, where, i, j, di, dj, default):
    for sign in (1, -1):
        other = where.get((i + sign * di, j + sign * dj))
        if other is not None:
            return sign * (candidates[other] - candidates[where[(i, j)]])
    return default


def fill_field(field: np.ndarray, valid: np.ndarray, iterations: int = 500) -> np.ndarray:
    """Fill the invalid entries of a lattice field (R, C, k) by harmonic interpolation.

    Valid entries stay; the others become the mean of their 4 neighbours (Jacobi sweeps,
    starting from the mean of the valid values), so gaps get smooth values from around them.
    """
    field = np.array(field, dtype=np.float64)
    valid = np.asarray(valid, dtype=bool)
    if valid.all():
        return field
    if not valid.any():
        raise TrackingError("fill_field needs at least one valid entry: no point of the lattice was measured; "
                            "check that the ROI covers the pattern")
    out = np.where(valid[..., None], field, np.nanmean(field[valid], axis=0))
    for _ in range(iterations):
        padded = np.pad(out, ((1, 1), (1, 1), (0, 0)), mode="edge")
        mean = 0.25 * (padded[:-2, 1:-1] + padded[2:, 1:-1] + padded[1:-1, :-2] + padded[1:-1, 2:])
        new = np.where(valid[..., None], out, mean)
        if np.max(np.abs(new - out)) < 1e-6:
            return new
        out = new
    return out


def fill_positions(nodes: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Positions for every lattice node (R, C, 2): an affine lattice fit plus a harmonic residual."""
    rows, cols = np.nonzero(valid)
    design = np.stack([np.ones(rows.size), rows, cols], axis=1).astype(np.float64)
    coef, *_ = np.linalg.lstsq(design, nodes[rows, cols], rcond=None)
    ii, jj = np.mgrid[0:nodes.shape[0], 0:nodes.shape[1]]
    affine = coef[0] + ii[..., None] * coef[1] + jj[..., None] * coef[2]
    residual = fill_field(np.where(valid[..., None], nodes - affine, 0.0), valid)
    return affine + residual


def interior_gaps(valid: np.ndarray) -> np.ndarray:
    """(R, C) bool: missing nodes with valid nodes on both sides in their row or their column."""
    def both_sides(v, axis):
        before = np.maximum.accumulate(v, axis=axis)
        after = np.flip(np.maximum.accumulate(np.flip(v, axis=axis), axis=axis), axis=axis)
        return before & after
    return ~valid & (both_sides(valid, 0) | both_sides(valid, 1))


def lattice_spacing(nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distances to the neighbours: along rows (R, C, 2) [left, right], columns (R, C, 2) [up, down].

    Missing neighbours give NaN.
    """
    def gaps(axis):
        diff = np.linalg.norm(np.diff(nodes, axis=axis), axis=-1)
        pad_before = [(0, 0), (0, 0)]
        pad_after = [(0, 0), (0, 0)]
        pad_before[axis] = (1, 0)
        pad_after[axis] = (0, 1)
        before = np.pad(diff, pad_before, constant_values=np.nan)
        after = np.pad(diff, pad_after, constant_values=np.nan)
        return np.stack([before, after], axis=-1)
    return gaps(1), gaps(0)
