"""track_images, image loading and the synthetic renderer's ground truth."""

import numpy as np
import pytest

from tracking import (ImageError, OptionError, TrackingError, deformed_points, grid_truth, load_images, render_grid,
                      render_speckle, smooth_displacement, track_images)
from tracking._synthetic import GridPattern, reference_points


def test_inverse_map_puts_material_points_where_the_field_says():
    field = smooth_displacement((100, 120), stretch=0.2, seed=3)
    x = np.linspace(0, 119, 50)
    y = np.linspace(0, 99, 50)
    rx, ry = reference_points(x, y, field)
    ux, uy = field(rx, ry)
    np.testing.assert_allclose(rx + ux, x, atol=1e-8)
    np.testing.assert_allclose(ry + uy, y, atol=1e-8)


def test_rendered_grid_crossings_are_where_the_truth_says():
    shape = (90, 100)
    field = smooth_displacement(shape, stretch=0.1, seed=1)
    image = render_grid(shape, 12.0, 2.0, field, blur_sigma=1.0)
    reference, deformed, index = grid_truth(shape, 12.0, field, margin=20)
    pattern = GridPattern(12.0, 2.0, origin=((shape[1] - 1) / 2 + 0.25, (shape[0] - 1) / 2 + 0.25))
    assert np.all(pattern.ink(reference[:, 0], reference[:, 1]) > 0.99)
    np.testing.assert_allclose(deformed, deformed_points(reference, field))
    # the darkest 3x3 neighbourhoods sit on the deformed crossings
    cols, rows = np.rint(deformed).astype(int).T
    assert image[rows, cols].mean() < image.mean() - 60


def test_track_images_dispatches_and_rejects_unknown_options(tmp_path):
    image = render_speckle((80, 90), noise_sigma=1.0)
    tracks = track_images([image, image], "speckle", spacing=20, subset=21)
    assert tracks.n_frames == 2 and not tracks.lost.any()
    np.testing.assert_allclose(tracks.displacements(), 0.0, atol=1e-3)
    with pytest.raises(TrackingError, match="unknown option"):
        track_images([image], "speckle", spacing=10, sbset=21)
    with pytest.raises(TrackingError, match="unknown pattern"):
        track_images([image], "dots")


def test_load_images_reads_png_and_tiff_as_float_grey(tmp_path):
    import cv2
    grey = (np.arange(40 * 50).reshape(40, 50) % 251).astype(np.uint8)
    colour = np.dstack([grey, grey, grey])
    cv2.imwrite(str(tmp_path / "a.png"), grey)
    cv2.imwrite(str(tmp_path / "b.tif"), colour)
    cv2.imwrite(str(tmp_path / "c.tif"), (grey.astype(np.uint16) * 257))
    stack = load_images([tmp_path / "a.png", tmp_path / "b.tif"])
    assert stack.dtype == np.float64 and stack.shape == (2, 40, 50)
    np.testing.assert_allclose(stack[0], grey)
    np.testing.assert_allclose(stack[1], grey, atol=0.51)
    assert load_images([tmp_path / "c.tif"])[0].max() > 255
    with pytest.raises(ImageError, match="not found"):
        load_images([tmp_path / "missing.png"])
    tracks = track_images([tmp_path / "a.png", tmp_path / "a.png"], "speckle", spacing=20, subset=11)
    assert tracks.n_frames == 2


def test_bad_options_raise_option_errors_that_are_value_errors():
    image = render_speckle((80, 90), noise_sigma=1.0)
    for options, message in (({"order": 7}, "spline order"), ({"subset": 20}, "odd number"),
                             ({"reference": "last"}, "'first' or 'previous'")):
        with pytest.raises(OptionError, match=message) as error:
            track_images([image, image], "speckle", spacing=20, **{"subset": 21, **options})
        assert isinstance(error.value, TrackingError) and isinstance(error.value, ValueError)


def test_fill_field_with_nothing_measured_is_a_tracking_error():
    from tracking._grid_topology import fill_field

    with pytest.raises(TrackingError, match="no point of the lattice was measured"):
        fill_field(np.zeros((3, 4, 2)), np.zeros((3, 4), bool))
