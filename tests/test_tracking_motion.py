"""Large motion between frames: the trackers estimate each frame's global motion first.

Generated images (``tracking._synthetic``) of a sheet clamped off the image's left side and
stretched towards its far end (in view, dark background beyond), with lighting gradient and grey
noise; the far end moves 0.9, 1.5 or 3 grid pitches per frame, or 20 % stretch in one pair.
"""

import numpy as np
import pytest
from scipy.spatial import cKDTree

from tracking import GridTracker, SpeckleTracker, deformed_points, grid_truth, render_grid, render_speckle
from tracking._lost import LOST_REASONS, MEASURED
from tracking._synthetic import Scene, clamped_displacement

SHAPE = (180, 260)
PITCH = 10.0
CLAMP, FAR_END = -10.0, 190.0


def _grid_sequence(strains, seed, scene):
    rng = np.random.default_rng(seed)
    centre_y = rng.uniform(80, 100)
    fields = [clamped_displacement(CLAMP, e, rng.uniform(0.2, 0.4), centre_y) for e in strains]
    images = [render_grid(SHAPE, PITCH, 2.0, f, noise_sigma=2.0, lighting_gradient=0.3, scene=scene,
                          seed=100 * seed + k) for k, f in enumerate(fields)]
    return images, fields


def check_grid_tracks(tracks, fields, scene=None):
    """RMS error of measured crossings per frame; asserts no slip and a reason for every loss."""
    reference, _, _ = grid_truth(SHAPE, PITCH, margin=-100)
    distance, match = cKDTree(reference).query(tracks.reference)
    assert distance.max() < 0.2
    truth = reference[match]
    if scene is not None:
        assert scene.material(truth[:, 0], truth[:, 1]).all(), "a point off the material"
    codes = tracks.meta["lost_reasons"]
    assert np.all((codes != MEASURED) == tracks.lost), "a lost point without its reason"
    assert set(np.unique(codes)) <= set(LOST_REASONS)
    rms = []
    for k, field in enumerate(fields):
        error = np.linalg.norm(tracks.positions[k] - deformed_points(truth, field), axis=1)[~tracks.lost[k]]
        assert error.max() < 0.5 * PITCH, f"frame {k}: a crossing slipped ({error.max():.2f} px)"
        rms.append(float(np.sqrt(np.mean(error ** 2))))
    return rms


@pytest.mark.parametrize("move, seed", [(0.9, 0), (1.5, 1), (3.0, 2)])
def test_grid_follows_motion_of_several_pitches_per_frame(move, seed):
    strain = move * PITCH / (FAR_END - CLAMP)
    scene = Scene(specimen=(-100.0, 30.0, FAR_END, 150.0))
    images, fields = _grid_sequence([0.0, strain, 2 * strain], seed, scene)
    tracks = GridTracker().track(images)
    rms = check_grid_tracks(tracks, fields, scene)
    assert max(rms) <= 0.05, rms
    # crossings well inside the material and the image stay measured
    inner = (tracks.reference[:, 1] > 45) & (tracks.reference[:, 1] < 135) & (tracks.reference[:, 0] > 15)
    assert tracks.n_points > 150
    assert tracks.lost[:, inner].mean() < 0.05


def test_grid_before_after_pair_at_20_percent_stretch():
    scene = Scene(specimen=(-100.0, 30.0, FAR_END, 150.0))
    images, fields = _grid_sequence([0.0, 0.2], 3, scene)
    tracks = GridTracker().track(images)
    rms = check_grid_tracks(tracks, fields, scene)
    assert max(rms) <= 0.05, rms
    assert tracks.meta["coarse_motion"][1]["supported"]
    assert tracks.lost[1].mean() < 0.1


@pytest.mark.parametrize("seed", [0, 1])
def test_speckle_follows_a_jump_of_a_tenth_of_the_roi(seed):
    rng = np.random.default_rng(seed)
    shape = (160, 160)
    angle = rng.uniform(0, 2 * np.pi)
    jump = 0.1 * 140 * np.array([np.cos(angle), np.sin(angle)])
    strain = rng.uniform(-0.02, 0.02)

    def field(x, y):
        return jump[0] + strain * (np.asarray(x) - 80), jump[1] - 0.3 * strain * (np.asarray(y) - 80)

    images = [render_speckle(shape, 1.2, None, noise_sigma=1.0, seed=seed),
              render_speckle(shape, 1.2, field, noise_sigma=1.0, seed=seed + 7)]
    tracks = SpeckleTracker(spacing=12, subset=21).track(images, roi=(10, 10, 150, 150))
    moved = ~tracks.lost[1]
    error = np.linalg.norm(tracks.positions[1] - deformed_points(tracks.reference, field), axis=1)[moved]
    assert np.sqrt(np.mean(error ** 2)) <= 0.05
    assert error.max() < 0.5
    # only points whose subset left the image may be lost, each with its reason
    target = deformed_points(tracks.reference, field)
    inside = np.all((target > 22) & (target < 138), axis=1)
    assert not np.any(tracks.lost[1] & inside)
    assert np.all((tracks.meta["lost_reasons"][1] != MEASURED) == tracks.lost[1])
