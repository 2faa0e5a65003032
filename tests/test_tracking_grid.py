"""Grid tracker: sub-pixel crossings, identities through deformation, lost points, errors."""

import numpy as np
import pytest
from scipy.spatial import cKDTree

from tracking import (GridNotFoundError, GridTracker, ImageError, RoiError, TrackingError, creased_displacement,
                      deformed_points, grid_truth, render_grid, scaled, smooth_displacement, track_images)

SHAPE = (200, 220)
ROI = (14, 14, 206, 186)


def _truth_of(tracks, shape, pitch, **grid):
    """True reference crossings matched to the tracked ones (must be within 0.2 px)."""
    reference, _, index = grid_truth(shape, pitch, margin=-100, **grid)
    distance, match = cKDTree(reference).query(tracks.reference)
    assert distance.max() < 0.2, "a reference crossing is far from every true crossing"
    return reference[match], index[match]


def _errors(tracks, truth_reference, displacement):
    true_positions = deformed_points(truth_reference, displacement)
    return np.linalg.norm(tracks.positions - true_positions, axis=-1)


@pytest.mark.parametrize("pitch, width, options", [
    (10.0, 2.0, {}),
    (14.0, 3.0, {"angle_deg": 6.0, "lighting_gradient": 0.3}),
    (20.0, 4.0, {"bright_lines": True}),
])
def test_reference_crossings_are_subpixel_accurate_and_complete(pitch, width, options):
    image = render_grid(SHAPE, pitch, width, noise_sigma=2.0, blur_sigma=1.0, seed=3, **options)
    tracks = track_images([image], "grid", roi=ROI)
    angle = options.get("angle_deg", 0.0)
    reference, _ = _truth_of(tracks, SHAPE, pitch, angle_deg=angle)
    error = np.linalg.norm(tracks.reference - reference, axis=1)
    assert np.sqrt(np.mean(error ** 2)) < 0.05
    assert error.max() < 0.15
    # every true crossing well inside the ROI is found
    truth, _, _ = grid_truth(SHAPE, pitch, angle_deg=angle)
    x0, y0, x1, y1 = ROI
    inner = truth[(truth[:, 0] > x0 + pitch) & (truth[:, 0] < x1 - pitch)
                  & (truth[:, 1] > y0 + pitch) & (truth[:, 1] < y1 - pitch)]
    assert cKDTree(tracks.reference).query(inner)[0].max() < 0.2
    assert tracks.meta["dark_lines"] == (not options.get("bright_lines", False))
    assert tracks.meta["pitch_px"] == pytest.approx(pitch, rel=0.01)


@pytest.mark.parametrize("seed", [0, 1])
def test_sequence_to_20_percent_stretch_keeps_accuracy_and_identities(seed):
    field = smooth_displacement(SHAPE, stretch=0.2, seed=seed)
    steps = np.linspace(0.0, 1.0, 5)
    images = [render_grid(SHAPE, 12.0, 2.0, scaled(field, s), noise_sigma=2.0, seed=10 * seed + k)
              for k, s in enumerate(steps)]
    tracks = track_images(images, "grid", roi=ROI)
    reference, index = _truth_of(tracks, SHAPE, 12.0)
    # topology: (row, col) follow the true lattice (one offset for all points)
    assert len({tuple(o) for o in tracks.grid_index - index}) == 1
    for k, s in enumerate(steps):
        truth = deformed_points(reference, scaled(field, s))
        error = np.linalg.norm(tracks.positions[k] - truth, axis=1)
        seen = ~tracks.lost[k]
        assert np.sqrt(np.mean(error[seen] ** 2)) < 0.05, f"frame {k}"
        assert error[seen].max() < 0.3, f"frame {k}: a point jumped to a wrong crossing"
        # only points leaving the image may be lost
        inside = np.all((truth > 10) & (truth < np.array(SHAPE[::-1]) - 10), axis=1)
        assert not np.any(tracks.lost[k] & inside), f"frame {k}: a visible point was lost"
    assert np.all(tracks.quality[~tracks.lost] > 0.8)


def test_line_fit_refinement_beats_hessian_and_snake_alone():
    field = smooth_displacement(SHAPE, stretch=0.15, seed=4)
    images = [render_grid(SHAPE, 12.0, 2.0, scaled(field, s), noise_sigma=2.0, seed=k)
              for k, s in enumerate([0.0, 1.0])]
    rms = {}
    for refiner in ("lines", "hessian", "snake"):
        tracks = GridTracker(refiner=refiner).track(images, roi=ROI)
        reference, _ = _truth_of(tracks, SHAPE, 12.0)
        error = _errors(tracks, reference, None)[0]
        moved = np.linalg.norm(tracks.positions[1] - deformed_points(reference, field), axis=1)
        both = np.concatenate([error, moved[~tracks.lost[1]]])
        rms[refiner] = np.sqrt(np.mean(both ** 2))
    assert rms["lines"] < 0.03
    assert rms["lines"] < 0.6 * rms["hessian"], rms
    assert rms["lines"] < 0.85 * rms["snake"], rms


def test_adaptive_line_shape_follows_creases_and_keeps_straight_accuracy():
    field, distance = creased_displacement(SHAPE, seed=5)
    images = [render_grid(SHAPE, 12.0, 2.0, scaled(field, s), noise_sigma=2.0, seed=20 + k)
              for k, s in enumerate([0.0, 0.5, 1.0])]
    rms = {}
    for shape in ("straight", "adaptive"):
        tracks = GridTracker(line_shape=shape).track(images, roi=ROI)
        reference, _ = _truth_of(tracks, SHAPE, 12.0)
        near = distance(reference) < 4.0
        seen = ~tracks.lost[2]
        error = np.linalg.norm(tracks.positions[2] - deformed_points(reference, field), axis=1)
        rest = np.linalg.norm(tracks.reference - reference, axis=1)
        rms[shape] = [np.sqrt(np.mean(e ** 2)) for e in (error[near & seen], error[~near & seen], rest)]
        assert tracks.meta["line_shape"] == shape
    # straight lines through a crease miss the crossing by ~0.15 px; the adaptive shape bends them
    assert rms["adaptive"][0] < 0.7 * rms["straight"][0], rms
    # away from creases and in the reference it stays about as accurate as straight lines
    assert rms["adaptive"][1] < 0.025 and rms["adaptive"][2] < 0.02, rms
    with pytest.raises(TrackingError, match="centre-line shape"):
        GridTracker(line_shape="wiggly").track(images, roi=ROI)


def test_occluded_crossings_are_lost_then_found_again():
    field = smooth_displacement(SHAPE, stretch=0.1, seed=2)
    steps = [0.0, 0.25, 0.5, 0.75, 1.0]
    images = [render_grid(SHAPE, 12.0, 2.0, scaled(field, s), noise_sigma=2.0, seed=k)
              for k, s in enumerate(steps)]
    yy, xx = np.mgrid[0:SHAPE[0], 0:SHAPE[1]]
    blot = (xx - 115) ** 2 + (yy - 95) ** 2 < 22 ** 2
    images[2] = np.where(blot, 200.0, images[2])
    tracks = track_images(images, "grid", roi=ROI)
    reference, _ = _truth_of(tracks, SHAPE, 12.0)
    truth = deformed_points(reference, scaled(field, steps[2]))
    under = blot[np.rint(truth[:, 1]).astype(int), np.rint(truth[:, 0]).astype(int)]
    assert under.sum() >= 8
    assert np.all(tracks.lost[2][under])
    assert np.all(np.isnan(tracks.positions[2][under]))
    seen = ~tracks.lost[2]
    assert np.linalg.norm(tracks.positions[2][seen] - truth[seen], axis=1).max() < 0.3
    for k in (3, 4):  # found again, at the right place
        truth = deformed_points(reference, scaled(field, steps[k]))
        assert not tracks.lost[k][under].any()
        assert np.linalg.norm(tracks.positions[k][under] - truth[under], axis=1).max() < 0.1


def test_no_grid_raises():
    flat = np.full(SHAPE, 120.0) + np.random.default_rng(0).normal(0, 2, SHAPE)
    with pytest.raises(GridNotFoundError):
        track_images([flat], "grid")


def test_bad_inputs_raise_clear_errors():
    image = render_grid(SHAPE, 12.0, 2.0)
    with pytest.raises(RoiError, match="outside"):
        track_images([image], "grid", roi=(0, 0, 500, 100))
    broken = image.copy()
    broken[5, 5] = np.nan
    with pytest.raises(ImageError, match="NaN"):
        track_images([image, broken], "grid")
    with pytest.raises(ImageError, match="same shape"):
        track_images([image, image[:-1]], "grid")


@pytest.mark.slow
@pytest.mark.parametrize("pitch, width", [(10.0, 2.0), (15.0, 3.0), (20.0, 4.0)])
def test_pitch_sweep_on_larger_images(pitch, width):
    shape = (400, 420)
    field = smooth_displacement(shape, stretch=0.2, seed=11)
    steps = np.linspace(0.0, 1.0, 6)
    images = [render_grid(shape, pitch, width, scaled(field, s), noise_sigma=2.0, seed=k)
              for k, s in enumerate(steps)]
    tracks = track_images(images, "grid", roi=(20, 20, 400, 380))
    reference, _ = _truth_of(tracks, shape, pitch)
    for k, s in enumerate(steps):
        truth = deformed_points(reference, scaled(field, s))
        seen = ~tracks.lost[k]
        error = np.linalg.norm(tracks.positions[k][seen] - truth[seen], axis=1)
        assert np.sqrt(np.mean(error ** 2)) < 0.05 and error.max() < 0.3


def test_blank_frame_loses_everything_and_tracking_resumes():
    field = smooth_displacement(SHAPE, stretch=0.08, seed=8)
    steps = [0.0, 0.25, 0.5, 0.75]
    images = [render_grid(SHAPE, 12.0, 2.0, scaled(field, s), noise_sigma=2.0, seed=k)
              for k, s in enumerate(steps)]
    images[2] = 200.0 + np.random.default_rng(0).normal(0, 2, SHAPE)
    tracks = track_images(images, "grid", roi=ROI)
    assert tracks.lost[2].all() and not tracks.lost[:2].any()
    reference, _ = _truth_of(tracks, SHAPE, 12.0)
    truth = deformed_points(reference, scaled(field, steps[3]))
    seen = ~tracks.lost[3]
    assert seen.mean() > 0.95
    assert np.linalg.norm(tracks.positions[3][seen] - truth[seen], axis=1).max() < 0.1
