"""A grid filling the whole view: no edge, hole or far end to fix the frame's translation.

The grid's coarse map (``tracking._coarse``) then has nothing on the material to correlate; the
image's own border (where the blur sees the pattern cut off) must not stand in for one, and a
map the crossings do not bear out must give way to the temporal prior or leave the crossings
lost: never written as slipped measurements. Generated images (``tracking._synthetic``, rendered
by supersampling, lighting gradient, grey noise) under seeds: random pitch 14-22 px, random
smooth stretch of 15-20 % reached over three frames.
"""

import numpy as np
import pytest
from scipy.spatial import cKDTree

import tracking._grid_tracker as grid_tracker
from tracking import GridTracker, deformed_points, grid_truth, render_grid, scaled, smooth_displacement
from tracking._coarse import CoarseMotion
from tracking._lost import LOST_REASONS, MEASURED, SLIP

SHAPE = (256, 256)
ROI = (16, 16, 240, 240)


def _case(seed):
    rng = np.random.default_rng(seed)
    pitch, stretch = rng.uniform(14.0, 22.0), rng.uniform(0.15, 0.20)
    field = smooth_displacement(SHAPE, stretch, seed=seed)
    fields = [scaled(field, s) for s in (0.0, 0.5, 1.0)]
    images = [render_grid(SHAPE, pitch, 3.0, f, noise_sigma=2.0, blur_sigma=1.0, seed=100 * seed + k,
                          quantize=True, lighting_gradient=0.2) for k, f in enumerate(fields)]
    return pitch, images, fields


def _errors(tracks, pitch, fields):
    """Per frame, the error (n,) px of each written crossing (NaN where lost)."""
    reference, _, _ = grid_truth(SHAPE, pitch, margin=-120)
    distance, match = cKDTree(reference).query(tracks.reference)
    assert distance.max() < 0.2
    codes = tracks.meta["lost_reasons"]
    assert np.all((codes != MEASURED) == tracks.lost), "a lost point without its reason"
    assert set(np.unique(codes)) <= set(LOST_REASONS)
    return [np.linalg.norm(tracks.positions[k] - deformed_points(reference[match], f), axis=1)
            for k, f in enumerate(fields)]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_grid_filling_the_view_tracks_a_large_stretch_without_slip(seed):
    pitch, images, fields = _case(seed)
    tracks = GridTracker().track(images, roi=ROI)
    for k, error in enumerate(_errors(tracks, pitch, fields)):
        written = error[np.isfinite(error)]
        assert written.max() < 0.5 * pitch, f"frame {k}: a crossing slipped ({written.max():.1f} px)"
        assert np.sqrt(np.mean(written ** 2)) <= 0.05, f"frame {k}: RMS {np.sqrt(np.mean(written ** 2)):.3f} px"
        assert written.size >= 0.7 * tracks.n_points, f"frame {k}: only {written.size} of {tracks.n_points}"
    # nothing on the material fixes a translation: the map is the prior, not "supported"
    assert not any(m["supported"] for m in tracks.meta["coarse_motion"][1:])


def _true_affine(pitch, field):
    """Least-squares affine map (CoarseMotion) of the true crossings' motion under ``field``."""
    reference, _, _ = grid_truth(SHAPE, pitch, margin=-120)
    design = np.hstack([reference, np.ones((len(reference), 1))])
    coef, *_ = np.linalg.lstsq(design, deformed_points(reference, field), rcond=None)
    return CoarseMotion(coef[:2].T, coef[2])


def test_a_supported_map_the_crossings_refute_writes_no_slip(monkeypatch):
    """A coarse map claimed supported whose translation is off by 0.4-0.6 pitch in x and in y
    (drawn under a seed; the true linear part): every crossing is more than half a pitch from
    it, so the crossings refute it and the tracker measures from the temporal prior instead.
    (A map off by a whole pitch is consistent with a grid filling the view: only what the
    silhouette sees on the material, or the frames before, can tell it.)"""
    pitch, images, fields = _case(3)
    rng = np.random.default_rng(3)
    wrong = rng.uniform(0.4, 0.6, 2) * pitch * rng.choice([-1, 1], 2)
    truths = iter([_true_affine(pitch, f) for f in fields[1:]])

    def wrong_motion(*args):
        truth = next(truths)
        return CoarseMotion(truth.linear, truth.offset + wrong, True, 0.9)

    monkeypatch.setattr(grid_tracker, "grid_motion", wrong_motion)
    tracks = GridTracker().track(images, roi=ROI)
    for k, error in enumerate(_errors(tracks, pitch, fields)):
        written = error[np.isfinite(error)]
        assert written.size == 0 or written.max() < 0.5 * pitch, f"frame {k}: slip written ({written.max():.1f} px)"
    # the prior measured more than the refuted map: it is taken, and marked unsupported
    assert not any(m["supported"] for m in tracks.meta["coarse_motion"][1:])
    assert np.count_nonzero(tracks.meta["lost_reasons"][1:] == SLIP) == 0
    assert (~tracks.lost[1:]).mean() >= 0.7
