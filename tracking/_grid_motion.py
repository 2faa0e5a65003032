"""Frame-to-frame motion of grid crossings: prediction, propagation from neighbours, jump checks.

Prediction is constant velocity per crossing (p_t = 2 p_{t-1} - p_{t-2}); where a crossing was
lost its displacement is filled smoothly from its neighbours. The prediction is then corrected
ring by ring outwards from a seed near the grid's centre: each crossing takes the mean correction
of its already matched neighbours before looking for the nearest detected crossing. So a large
but smooth deformation is followed as long as the seed itself moves less than a third of a pitch
beyond its prediction; the grid tracker makes that so by predicting from the frame's global
motion (``_coarse``) plus each crossing's residual (:func:`affine_fit` splits the two).
"""

from __future__ import annotations

import warnings
from collections import deque

import numpy as np
from scipy.spatial import cKDTree

from ._coarse import CoarseMotion
from ._grid_topology import NEIGHBOURS, fill_field

_RING = tuple((di, dj) for di in (-1, 0, 1) for dj in (-1, 0, 1) if (di, dj) != (0, 0))


def predict(history: list[np.ndarray], active: np.ndarray) -> np.ndarray:
    """Predicted crossings (R, C, 2) for the next frame from the past ones (each (R, C, 2), NaN lost).

    Constant velocity where the last two frames have the crossing; otherwise its last known
    displacement, or (never seen since frame 0) its neighbours' displacements, filled harmonically.
    """
    reference = history[0]
    last = np.full(reference.shape, np.nan)
    for frame in history:                     # the most recent position each crossing had
        last = np.where(np.isfinite(frame), frame, last)
    displacement = last - reference
    valid = np.isfinite(displacement[..., 0]) & active
    displacement = fill_field(np.where(valid[..., None], displacement, 0.0), valid) if valid.any() \
        else np.zeros_like(displacement)
    if len(history) >= 2:
        velocity = history[-1] - history[-2]
        moving = np.isfinite(velocity[..., 0]) & active
        if moving.any():
            velocity = fill_field(np.where(moving[..., None], velocity, 0.0), moving)
            displacement = displacement + velocity
    out = reference + displacement
    out[~active] = np.nan
    return out


def _layers(active: np.ndarray, seed: tuple[int, int]) -> list[list[tuple[int, int]]]:
    depth = {seed: 0}
    queue = deque([seed])
    order = []
    while queue:
        node = queue.popleft()
        order.append(node)
        for di, dj in NEIGHBOURS:
            other = (node[0] + di, node[1] + dj)
            if (0 <= other[0] < active.shape[0] and 0 <= other[1] < active.shape[1]
                    and active[other] and other not in depth):
                depth[other] = depth[node] + 1
                queue.append(other)
    layers = [[] for _ in range(max(depth.values()) + 1)]
    for node in order:
        layers[depth[node]].append(node)
    return layers


def propagate(predicted: np.ndarray, active: np.ndarray, candidates: np.ndarray,
              radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Correct a prediction (R, C, 2) with detected crossings (m, 2), ring by ring from a seed.

    Returns the corrected positions (R, C, 2) (NaN where inactive) and a (R, C) bool of
    crossings that matched a detection within ``radius`` px.
    """
    corrected = np.full(predicted.shape, np.nan)
    matched = np.zeros(active.shape, bool)
    if len(candidates) == 0:
        corrected[active] = predicted[active]
        return corrected, matched
    tree = cKDTree(candidates)
    correction = np.zeros(predicted.shape)
    done = np.zeros(active.shape, bool)
    taken = set()
    while True:
        left = np.argwhere(active & ~done)
        if len(left) == 0:
            break
        seed = _seed(predicted, left, tree, radius)
        for layer in _layers(active & ~done, seed):
            guess = np.array([predicted[n] + _mean_correction(correction, done, n) for n in layer])
            distance, found = tree.query(guess)
            order = np.argsort(distance)
            for k in order:
                node = layer[k]
                hit = distance[k] <= radius and found[k] not in taken
                if hit:
                    taken.add(found[k])
                    correction[node] = candidates[found[k]] - predicted[node]
                    matched[node] = True
                else:
                    correction[node] = guess[k] - predicted[node]
                done[node] = True
    corrected[active] = (predicted + correction)[active]
    return corrected, matched


def _seed(predicted, left, tree, radius):
    """The remaining crossing nearest the centre of the remaining ones that has a detection near it."""
    points = predicted[left[:, 0], left[:, 1]]
    order = np.argsort(np.linalg.norm(points - points.mean(axis=0), axis=1))
    for k in order[:25]:
        if tree.query(points[k])[0] <= radius:
            return tuple(left[k])
    return tuple(left[order[0]])


def _mean_correction(correction, done, node):
    total, count = np.zeros(2), 0
    for di, dj in _RING:
        i, j = node[0] + di, node[1] + dj
        if 0 <= i < done.shape[0] and 0 <= j < done.shape[1] and done[i, j]:
            total += correction[i, j]
            count += 1
    return total / count if count else total


def jumps(step: np.ndarray, valid: np.ndarray, limit: float) -> np.ndarray:
    """(R, C) bool: crossings whose motion ``step`` (R, C, 2) differs from the median of their
    valid 8-neighbours' by more than ``limit`` px (a likely jump to the wrong crossing)."""
    rows, cols = valid.shape
    padded = np.pad(np.where(valid[..., None], step, np.nan), ((1, 1), (1, 1), (0, 0)),
                    constant_values=np.nan)
    around = np.stack([padded[1 + di:1 + di + rows, 1 + dj:1 + dj + cols] for di, dj in _RING])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)      # all-NaN neighbourhoods
        median = np.nanmedian(around, axis=0)
    count = np.sum(np.isfinite(around[..., 0]), axis=0)
    off = np.linalg.norm(step - median, axis=-1)
    return valid & (count >= 2) & (off > limit)


def affine_fit(reference: np.ndarray, positions: np.ndarray, active: np.ndarray) -> CoarseMotion:
    """Least-squares affine map of the reference crossings (R, C, 2) to ``positions`` (R, C, 2),
    over the active crossings seen in both (identity if fewer than 3); not marked supported."""
    seen = active & np.isfinite(positions[..., 0]) & np.isfinite(reference[..., 0])
    if np.count_nonzero(seen) < 3:
        return CoarseMotion(np.eye(2), np.zeros(2))
    design = np.hstack([reference[seen], np.ones((np.count_nonzero(seen), 1))])
    coef, *_ = np.linalg.lstsq(design, positions[seen], rcond=None)
    return CoarseMotion(coef[:2].T, coef[2])
