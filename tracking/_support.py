"""Whether a measured motion is supported by its neighbours' (a subset that matched the wrong place).

A subset can match well somewhere it did not go: where the texture changed between frames (a
scratch, a flake, a reflection), near an edge, or after a start a subset off. Its correlation
may still pass, but its motion disagrees with the points around it. Each neighbour j on the
points' lattice predicts point i's displacement to first order from its own displacement and
gradient, d_j + G_j (x_i - x_j); a point farther than a threshold from the median of those
predictions is unsupported. The median keeps a few bad neighbours from hiding (or framing) a
point; flagged points stop predicting and the test is repeated, so a patch of bad matches is
peeled from its border inwards.
"""

from __future__ import annotations

import numpy as np

NEIGHBOURS = [(di, dj) for di in (-1, 0, 1) for dj in (-1, 0, 1) if (di, dj) != (0, 0)]


def neighbour_disagreement(index: np.ndarray, origin: np.ndarray, displacement: np.ndarray,
                           gradient: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance (n,) px of each displacement from its lattice neighbours' median prediction.

    Args:
        index: (n, 2) lattice (row, col) of the points.
        origin: (n, 2) px where each measured motion starts (the point in the frame matched from).
        displacement: (n, 2) px measured motion.
        gradient: (n, 2, 2) its gradient d displacement / d origin (IC-GN's ux, uy; vx, vy).
        valid: (n,) bool, the points that predict (measured and not yet flagged).

    Returns:
        The distance (n,) (NaN where fewer than two valid neighbours predict) and the number of
        predicting neighbours (n,).
    """
    index = np.asarray(index, np.int64)
    rows, cols = index[:, 0].max() + 3, index[:, 1].max() + 3
    slot = -np.ones((rows, cols), np.int64)
    slot[index[:, 0] + 1, index[:, 1] + 1] = np.arange(len(index))
    predictions = np.full((len(NEIGHBOURS), len(index), 2), np.nan)
    for k, (di, dj) in enumerate(NEIGHBOURS):
        j = slot[index[:, 0] + 1 + di, index[:, 1] + 1 + dj]
        use = (j >= 0) & valid[np.maximum(j, 0)]
        js = j[use]
        step = origin[use] - origin[js]
        predictions[k, use] = displacement[js] + np.einsum("nab,nb->na", gradient[js], step)
    count = np.isfinite(predictions[..., 0]).sum(axis=0)
    median = np.full((len(index), 2), np.nan)
    judged = count >= 2
    median[judged] = np.nanmedian(predictions[:, judged], axis=0)
    return np.linalg.norm(displacement - median, axis=1), count


def unsupported(index: np.ndarray, origin: np.ndarray, displacement: np.ndarray, gradient: np.ndarray,
                valid: np.ndarray, tolerance: float, rounds: int = 4) -> np.ndarray:
    """(n,) bool: valid points whose motion their neighbours do not support (see the module).

    The threshold is ``tolerance`` px or six robust standard deviations of the distances
    (1.4826 times their median), whichever is larger, so a noisy or strongly strained field does
    not lose good points. A point with fewer than two measured neighbours is not judged here.
    """
    valid = np.asarray(valid, bool).copy()
    flagged = np.zeros(len(valid), bool)
    for _ in range(rounds):
        distance, _ = neighbour_disagreement(index, origin, displacement, gradient, valid)
        judged = valid & np.isfinite(distance)
        if not judged.any():
            break
        threshold = max(tolerance, 6.0 * 1.4826 * float(np.median(distance[judged])))
        new = judged & (distance > threshold)
        if not new.any():
            break
        flagged |= new
        valid &= ~new
    return flagged
