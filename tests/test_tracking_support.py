"""The speckle tracker writes no match the data do not support, and follows jumps frame to frame.

- A patch of the speckle replaced between frames (a flake, a scratch, a reflection; random place
  and size under seeds): subsets on it must come out lost with a reason, or right; none wrong.
- ``reference="previous"`` uses each frame's global motion (estimated against the previous frame):
  a sequence that jumps a tenth of the ROI per frame, in a new direction every frame.
"""

import numpy as np
import pytest

from tracking import SpeckleTracker, deformed_points, render_speckle
from tracking._lost import JUMP, MEASURED, REJECTED, SLIP

SHAPE = (160, 160)
ROI = (10, 10, 150, 150)


def _smooth_field(rng):
    """A random affine-plus-quadratic displacement (px) about the image centre."""
    a = rng.uniform(-0.02, 0.02, 4)
    t = rng.uniform(-3.0, 3.0, 2)

    def field(x, y):
        x, y = np.asarray(x) - 80.0, np.asarray(y) - 80.0
        return t[0] + a[0] * x + a[1] * y + 2e-4 * x * y, t[1] + a[2] * x + a[3] * y
    return field


@pytest.mark.parametrize("seed", [0, 3])
def test_a_patch_with_new_texture_is_lost_with_reasons_not_measured_wrong(seed):
    rng = np.random.default_rng(seed)
    field = _smooth_field(rng)
    reference = render_speckle(SHAPE, 1.2, None, noise_sigma=1.0, seed=seed)
    image = render_speckle(SHAPE, 1.2, field, noise_sigma=1.0, seed=seed + 7)
    other = render_speckle(SHAPE, 1.2, field, noise_sigma=1.0, seed=seed + 9, pattern_seed=seed + 50)
    half = int(rng.uniform(10, 15))
    cx, cy = rng.integers(40, 120, 2)
    patch = (slice(cy - half, cy + half), slice(cx - half, cx + half))
    image[patch] = other[patch]
    tracks = SpeckleTracker(spacing=8, subset=21).track([reference, image], roi=ROI)
    truth = deformed_points(tracks.reference, field)
    error = np.linalg.norm(tracks.positions[1] - truth, axis=1)
    codes = tracks.meta["lost_reasons"][1]
    radius = 10 + half
    on_patch = np.all(np.abs(truth - (cx, cy)) < radius, axis=1)    # subset meets the patch
    measured = ~tracks.lost[1]
    assert np.all((codes != MEASURED) == tracks.lost[1])
    # on the patch: lost with a reason of its own, or measured right; most are lost
    assert np.all(np.isin(codes[on_patch & ~measured], [REJECTED, SLIP, JUMP]))
    assert tracks.lost[1, on_patch].mean() > 0.5
    assert np.all(error[on_patch & measured] < 0.1), error[on_patch & measured]
    # and the check loses nothing else
    assert not tracks.lost[1, ~on_patch].any()
    assert np.sqrt(np.mean(error[~on_patch] ** 2)) <= 0.02


def test_reference_previous_follows_jumps_that_change_direction():
    # jumps of 9 px, a tenth of the 90 px ROI, in random directions
    rng = np.random.default_rng(5)
    jumps = 9.0 * np.array([[np.cos(a), np.sin(a)] for a in rng.uniform(0, 2 * np.pi, 3)])
    offsets = np.cumsum(jumps, axis=0)
    strain = rng.uniform(0.01, 0.02)

    def field(k):
        def u(x, y):
            x, y = np.asarray(x) - 80.0, np.asarray(y) - 80.0
            return offsets[k, 0] + k * strain * x, offsets[k, 1] - 0.3 * k * strain * y
        return u

    images = [render_speckle((200, 200), 1.2, None, noise_sigma=1.0, seed=0)]
    images += [render_speckle((200, 200), 1.2, field(k), noise_sigma=1.0, seed=k + 1) for k in range(3)]
    tracks = SpeckleTracker(spacing=12, subset=21, reference="previous").track(images, roi=(55, 55, 145, 145))
    assert all(m["supported"] for m in tracks.meta["coarse_motion"])
    for k in range(1, 4):
        truth = deformed_points(tracks.reference, field(k - 1))
        inside = np.all((truth > 12) & (truth < 188), axis=1)
        assert not tracks.lost[k, inside].any(), f"frame {k}: {tracks.lost[k, inside].sum()} lost"
        error = np.linalg.norm(tracks.positions[k] - truth, axis=1)[~tracks.lost[k]]
        assert np.sqrt(np.mean(error ** 2)) <= 0.05, (k, np.sqrt(np.mean(error ** 2)))
