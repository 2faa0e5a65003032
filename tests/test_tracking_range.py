"""Range images: depth lookup with holes reported as lost, 3D coordinates of tracks."""

import numpy as np
import pytest

from tracking import TrackingError, Tracks, points_3d, range_lookup, render_range

SHAPE = (60, 80)


def test_bilinear_is_exact_on_a_plane_and_bicubic_on_a_cubic():
    rng = np.random.default_rng(0)
    xy = rng.uniform([3, 3], [SHAPE[1] - 4, SHAPE[0] - 4], size=(200, 2))
    plane = render_range(lambda x, y: 5.0 + 0.1 * x - 0.05 * y, SHAPE)
    z, lost = range_lookup(plane, xy, order=1)
    np.testing.assert_allclose(z, 5.0 + 0.1 * xy[:, 0] - 0.05 * xy[:, 1], atol=1e-12)
    assert not lost.any()
    def surface(x, y):
        return 1e-4 * (x - 40) ** 2 * (y - 10) + 0.01 * y ** 2
    curved = render_range(surface, SHAPE)
    z3, _ = range_lookup(curved, xy, order=3)
    z1, _ = range_lookup(curved, xy, order=1)
    exact = surface(xy[:, 0], xy[:, 1])
    assert np.abs(z3 - exact).max() < 0.2 * np.abs(z1 - exact).max()


@pytest.mark.parametrize("order, reach", [(1, 1.0), (3, 2.0)])
def test_points_over_holes_are_lost_not_invented(order, reach):
    z_image = render_range(lambda x, y: 100.0 + 0 * x, SHAPE, holes=[(40.0, 30.0, 5.0)])
    xy = np.array([[40.0, 30.0], [40.0 + 5 + reach - 0.5, 30.0], [40.0 + 5 + reach + 0.6, 30.0],
                   [0.5, 0.5], [np.nan, 3.0], [79.5, 10.0]])
    z, lost = range_lookup(z_image, xy, order=order)
    assert lost.tolist() == [True, True, False, order == 3, True, True]
    assert np.all(np.isnan(z[lost])) and np.allclose(z[~lost], 100.0)


def test_invalid_value_code_counts_as_hole():
    z_image = np.full(SHAPE, 3.0)
    z_image[10:14, 10:14] = -9999.0
    z, lost = range_lookup(z_image, np.array([[11.5, 11.5], [30.2, 30.7]]), invalid_value=-9999.0)
    assert lost.tolist() == [True, False] and z[1] == pytest.approx(3.0)


def test_points_3d_combines_tracking_and_range_losses():
    reference = np.array([[20.0, 20.0], [50.0, 30.0], [60.0, 40.0]])
    positions = np.stack([reference, reference + [1.0, 0.5]])
    lost = np.array([[False, False, False], [False, True, False]])
    positions[lost] = np.nan
    tracks = Tracks(ids=[1, 2, 3], reference=reference, positions=positions, lost=lost,
                    quality=np.ones((2, 3)), grid_index=-np.ones((3, 2)))
    ranges = [render_range(lambda x, y: 0.5 * x + 0 * y, SHAPE),
              render_range(lambda x, y: 0.5 * x + 1 + 0 * y, SHAPE, holes=[(21.0, 20.5, 2.0)])]
    xyz, gone = points_3d(tracks, ranges)
    assert gone.tolist() == [[False, False, False], [True, True, False]]
    np.testing.assert_allclose(xyz[0, :, 2], [10.0, 25.0, 30.0])
    np.testing.assert_allclose(xyz[1, 2], [61.0, 40.5, 31.5])
    with pytest.raises(TrackingError):
        points_3d(tracks, ranges[:1])


def test_lost_points_carry_their_reason():
    from tracking import _lost as codes

    z_image = render_range(lambda x, y: 7.0 + 0.01 * x + 0 * y, SHAPE, holes=[(40.0, 30.0, 4.0)])
    z_image[5, 5] = -1.0  # the scanner's no-data code
    xy = np.array([[40.0, 30.0], [5.3, 5.2], [0.3, 20.0], [np.nan, 4.0], [20.25, 10.75]])
    for order, off_edge in ((1, False), (3, True)):  # bicubic needs a pixel left of column 0
        z, lost, why = range_lookup(z_image, xy, order=order, invalid_value=-1.0, explain=True)
        expect = [codes.NO_RANGE, codes.NO_RANGE, codes.OFF_RANGE if off_edge else codes.MEASURED,
                  codes.NOT_SEEN, codes.MEASURED]
        assert why.tolist() == expect and lost.tolist() == [e != codes.MEASURED for e in expect]
        assert z[4] == pytest.approx(7.0 + 0.01 * 20.25, abs=1e-12)  # sub-pixel, exact on a plane
        assert codes.LOST_REASONS[codes.NO_RANGE].startswith("no range data")


def test_points_3d_explains_tracking_and_range_losses():
    from tracking import _lost as codes

    reference = np.array([[20.0, 20.0], [50.0, 30.0], [60.0, 40.0]])
    positions = np.stack([reference, reference + [1.0, 0.5]])
    lost = np.array([[False, False, False], [False, True, False]])
    positions[lost] = np.nan
    reasons = np.where(lost, codes.JUMP, 0).astype(np.int8)
    tracks = Tracks(ids=[1, 2, 3], reference=reference, positions=positions, lost=lost, quality=np.ones((2, 3)),
                    grid_index=-np.ones((3, 2)), meta={"lost_reasons": reasons})
    ranges = [render_range(lambda x, y: 0.5 * x + 0 * y, SHAPE),
              render_range(lambda x, y: 0.5 * x + 0 * y, SHAPE, holes=[(21.0, 20.5, 2.0)])]
    _, gone, why = points_3d(tracks, ranges, explain=True)
    assert why.tolist() == [[0, 0, 0], [codes.NO_RANGE, codes.JUMP, 0]] and gone.tolist() == [[0, 0, 0], [1, 1, 0]]
