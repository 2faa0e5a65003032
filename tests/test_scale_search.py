"""The diagnosis at scale: the drive's covariance from the per-frame blocks of the drive
Jacobian (never the frames x frames array) equals the one from the whole Jacobian. Random
arrays under a seed, some points lost in some frames (no model: pure bookkeeping)."""

import numpy as np

from refine.diagnosis.uncertainty import _frame_blocks
from refine.measures import Residuals


def test_drive_blocks_give_the_whole_jacobians_product():
    rng = np.random.default_rng(17)
    frames, points, dim, m, k = 4, 30, 2, 7, 3
    disp = rng.normal(size=(frames, points, dim))
    disp[rng.random((frames, points)) < 0.15] = np.nan  # lost points: fewer rows in their frames
    mask = rng.random(points) < 0.7
    res = Residuals.at(disp, mask, sigma=0.3)
    blocks = rng.normal(size=(frames, points, dim, m))
    whole = np.zeros((frames, points, dim, frames, m))
    for f in range(frames):
        whole[f, :, :, f] = blocks[f]
    J = rng.normal(size=(res.n, k))
    want = J.T @ res.jacobian(whole.reshape(frames, points, dim, -1))
    got = _frame_blocks(J, res, blocks)
    assert got.shape == (k, frames * m)
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)
