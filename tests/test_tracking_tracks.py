"""Tracks: the result type, its checks and conversions."""

import numpy as np
import pytest

from tracking import Tracks, TrackingError, scale_from_grid


def _tracks(n_frames=3):
    reference = np.array([[10.0, 20.0], [22.0, 20.0], [10.0, 32.0], [22.0, 32.0]])
    shift = np.arange(n_frames)[:, None, None] * np.array([0.5, -0.25])
    positions = reference[None] + shift
    lost = np.zeros((n_frames, 4), bool)
    lost[2, 1] = True
    positions[lost] = np.nan
    return Tracks(ids=[1, 2, 3, 4], reference=reference, positions=positions, lost=lost,
                  quality=np.ones((n_frames, 4)), grid_index=[[0, 0], [0, 1], [1, 0], [1, 1]],
                  quality_kind="symmetry")


def test_displacements_and_reliable():
    tracks = _tracks()
    d = tracks.displacements()
    assert d.shape == (3, 4, 2)
    np.testing.assert_allclose(d[1], [[0.5, -0.25]] * 4)
    assert np.isnan(d[2, 1]).all()
    assert tracks.reliable(0.5).sum() == 11
    assert (tracks.n_frames, tracks.n_points) == (3, 4)


def test_arrays_are_read_only():
    tracks = _tracks()
    with pytest.raises(ValueError):
        tracks.positions[0, 0, 0] = 1.0


def test_to_length_scales_about_origin():
    tracks = _tracks()
    mm = tracks.to_length(0.1, origin=(10.0, 20.0))
    np.testing.assert_allclose(mm.reference[1], [1.2, 0.0])
    np.testing.assert_allclose(mm.displacements()[1, 0], [0.05, -0.025])
    assert mm.units == "mm" and np.isnan(mm.positions[2, 1]).all()
    with pytest.raises(TrackingError):
        mm.to_length(0.1)
    with pytest.raises(TrackingError):
        tracks.to_length(-1.0)


def test_scale_from_grid():
    assert scale_from_grid(_tracks(), pitch_mm=3.0) == pytest.approx(0.25)


def test_inconsistent_tracks_are_refused():
    good = _tracks()
    with pytest.raises(TrackingError, match="lost"):
        Tracks(ids=good.ids, reference=good.reference, positions=np.nan_to_num(good.positions),
               lost=good.lost, quality=good.quality, grid_index=good.grid_index)
    with pytest.raises(TrackingError, match="unique"):
        Tracks(ids=[1, 1, 2, 3], reference=good.reference, positions=good.positions, lost=good.lost,
               quality=good.quality, grid_index=good.grid_index)
    with pytest.raises(TrackingError):
        Tracks(ids=good.ids, reference=good.reference, positions=good.positions[:, :3], lost=good.lost,
               quality=good.quality, grid_index=good.grid_index)
