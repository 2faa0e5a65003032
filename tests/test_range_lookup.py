"""Range images in: the sub-pixel depth lookup from valid pixels only, occluding edges, the camera
models and pose, the range files (.npy, float TIFF) and clouds thinned on a voxel grid."""

import numpy as np
import pytest

import tracking
from tracking import _lost as codes
from tracking import Camera, cell_pixels, load_range_images, range_cloud, range_lookup

SHAPE = (80, 100)


def curved(x, y):
    """A tilted, curved depth surface in px coordinates (mm of depth): slopes 0.03 and 0.012 mm/px,
    a sphere-like bulge of radius 3000 px (300 mm at 0.1 mm/px)."""
    return 50.0 + 0.03 * x + 0.012 * y + ((x - 40.0) ** 2 + (y - 35.0) ** 2) / (2 * 3000.0)


def test_subpixel_lookup_on_a_tilted_curved_surface_uses_valid_neighbours_only():
    rng = np.random.default_rng(11)
    image = tracking.render_range(curved, SHAPE)
    holes = rng.random(SHAPE) < 0.08                       # scanner drop-outs, single pixels at random
    image[holes] = np.nan
    xy = rng.uniform([1, 1], [SHAPE[1] - 2, SHAPE[0] - 2], size=(3000, 2))
    z, lost, why = range_lookup(image, xy, explain=True)
    x0, y0 = np.floor(xy).astype(int).T
    support = np.stack([holes[y0, x0], holes[y0, x0 + 1], holes[y0 + 1, x0], holes[y0 + 1, x0 + 1]], 1)
    nearest = holes[np.rint(xy[:, 1]).astype(int), np.rint(xy[:, 0]).astype(int)]
    expect_lost = nearest | (support.sum(1) >= 2)
    np.testing.assert_array_equal(lost, expect_lost)
    assert set(why[lost].tolist()) == {codes.NO_RANGE} and np.all(np.isnan(z[lost]))
    partial = ~lost & support.any(1)
    assert partial.sum() > 100                              # the plane through three pixels was used
    err = np.abs(z[~lost] - curved(*xy[~lost].T))
    step = np.hypot(0.03, 0.012)                            # the depth step of one pixel, mm
    # bilinear / three-pixel plane on a surface of curvature 1/3000 px: error <= h^2 z'' / 4 ~ 1e-4 mm
    assert err.max() < 0.01 * step, (err.max(), step)
    assert np.abs(z[partial] - curved(*xy[partial].T)).max() < 0.01 * step


def test_quadratic_fit_is_exact_on_a_quadric_and_averages_the_noise_down():
    rng = np.random.default_rng(3)
    xy = rng.uniform([4, 4], [SHAPE[1] - 5, SHAPE[0] - 5], size=(1500, 2))
    clean = tracking.render_range(curved, SHAPE)
    z, lost = range_lookup(clean, xy, order=2)
    assert not lost.any() and np.abs(z - curved(*xy.T)).max() < 1e-9
    noisy = clean + rng.normal(0.0, 0.05, SHAPE)
    noisy[rng.random(SHAPE) < 0.05] = np.nan
    rms = {}
    for order in (1, 2):
        z, lost = range_lookup(noisy, xy, order=order)
        rms[order] = np.sqrt(np.mean((z - curved(*xy.T))[~lost] ** 2))
    # bilinear: 0.05 x sqrt(sum w^2) ~ 0.035 rms; a quadratic on ~24 pixels ~ 0.02 (measured 0.034 / 0.020)
    assert rms[2] < 0.7 * rms[1] and rms[2] < 0.5 * 0.05, rms
    window = np.full(SHAPE, np.nan)
    window[10:13, 10:13] = 1.0                     # 9 valid pixels: too few of the 25 -> lost
    z, lost, why = range_lookup(window, np.array([[11.2, 11.1], [np.nan, 1.0]]), order=2, explain=True)
    assert why.tolist() == [codes.NO_RANGE, codes.NOT_SEEN]


def test_an_occluding_edge_is_lost_with_its_reason_not_interpolated():
    image = tracking.render_range(lambda x, y: np.where(x < 50, 40.0, 55.0) + 0.01 * y, SHAPE)
    xy = np.array([[49.5, 20.0], [30.3, 20.0], [70.6, 40.2], [49.8, 10.0]])
    z, lost, why = range_lookup(image, xy, explain=True, max_step=2.0)
    assert why.tolist() == [codes.RANGE_EDGE, 0, 0, codes.RANGE_EDGE]
    assert z[1] == pytest.approx(40.2) and z[2] == pytest.approx(55.402)
    assert "occluding edge" in codes.LOST_REASONS[codes.RANGE_EDGE]
    _, lost_without = range_lookup(image, xy)               # no max_step: no edge test
    assert not lost_without.any()


@pytest.mark.parametrize("model", ["orthographic", "perspective"])
def test_camera_maps_pixels_and_depth_to_world_and_back(model, tmp_path):
    angle = 0.3
    R = np.array([[np.cos(angle), -np.sin(angle), 0], [np.sin(angle), np.cos(angle), 0], [0, 0, 1]])
    keys = dict(scale=0.08, cx=3.0, cy=-2.0) if model == "orthographic" else dict(fx=1500.0, fy=1480.0, cx=320.0,
                                                                                   cy=240.0)
    camera = Camera(model, rotation=R, translation=[1.0, 2.0, -80.0], **keys)
    rng = np.random.default_rng(0)
    uv, depth = rng.uniform(0, 600, (50, 2)), rng.uniform(70, 90, 50)
    world = camera.to_world(uv, depth)
    back, d = camera.project(world)
    np.testing.assert_allclose(back, uv, atol=1e-9)
    np.testing.assert_allclose(d, depth, atol=1e-12)
    if model == "perspective":   # a ray: points of one pixel at two depths lie on a line through the centre
        a, b = camera.to_world(uv[:1], [70.0]), camera.to_world(uv[:1], [140.0])
        np.testing.assert_allclose(b - camera.translation, 2 * (a - camera.translation), atol=1e-9)
    import tomli_w

    (tmp_path / "cam.toml").write_text(tomli_w.dumps(camera.to_toml()))
    again = tracking.read_camera(tmp_path / "cam.toml")
    np.testing.assert_allclose(again.to_world(uv, depth), world, atol=1e-12)


def test_camera_bad_input_says_what_to_write(tmp_path):
    (tmp_path / "c.toml").write_text('model = "perspective"\nfx = 1.0\nfy = 1.0\ncx = 0.0\ncy = 0.0\nfz = 2.0\n')
    with pytest.raises(tracking.OptionError, match="'fz'.*did you mean"):
        tracking.read_camera(tmp_path / "c.toml")
    with pytest.raises(tracking.OptionError, match="needs fx, fy, cx, cy"):
        tracking.camera_from_table({"model": "perspective", "fx": 10.0})
    with pytest.raises(tracking.OptionError, match="rotation matrix"):
        Camera(rotation=np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(tracking.OptionError, match="unknown"):
        Camera("fisheye")


def test_range_files_npy_and_float_tiff_with_no_data_as_nan_and_an_empty_frame_refused(tmp_path):
    import tifffile

    a = tracking.render_range(curved, SHAPE).astype(np.float32)
    a[3, 4] = 0.0                                           # 0: no data
    b = a + 0.5
    b[10, 10] = np.nan
    np.save(tmp_path / "r_1.npy", a)
    tifffile.imwrite(tmp_path / "r_2.tif", b)
    stack, names = load_range_images(tmp_path)
    assert stack.shape == (2, *SHAPE) and names == ["r_1.npy", "r_2.tif"]
    assert np.isnan(stack[0, 3, 4]) and np.isnan(stack[1, 10, 10]) and np.isfinite(stack).sum() == 2 * a.size - 2
    np.testing.assert_allclose(stack[1, 20, 30], b[20, 30])
    np.save(tmp_path / "r_3.npy", np.zeros(SHAPE, np.float32))
    with pytest.raises(tracking.ImageError, match=r"r_3.npy \(frame 2\) has no range data"):
        load_range_images(tmp_path)
    np.save(tmp_path / "stack.npy", np.stack([a, b]))
    stack2, names2 = load_range_images(tmp_path / "stack.npy")
    assert stack2.shape == (2, *SHAPE) and names2 == ["stack.npy[0]", "stack.npy[1]"]


def test_clouds_from_a_range_image_lie_on_the_surface_within_the_noise():
    rng = np.random.default_rng(5)
    camera = Camera("orthographic", scale=0.1, cx=50.0, cy=40.0, translation=[0.0, 0.0, -50.0])
    noise = 0.05
    clean = tracking.render_range(curved, SHAPE)
    noisy = clean + rng.normal(0, noise, SHAPE)
    noisy[20:30, 60:75] = np.nan                            # a hole in the scan
    mask = np.zeros(SHAPE, bool)
    mask[5:75, 5:95] = True
    spacing = 0.4
    cloud = range_cloud(noisy, camera, spacing, mask)
    uv, _ = camera.project(cloud)
    truth = camera.to_world(uv, curved(*uv.T))[:, 2]
    err = cloud[:, 2] - truth
    # 16 pixels per cell: the mean's noise is ~noise / 4 (the surface's tilt adds nothing: the mean of
    # a plane's points lies on the plane)
    assert np.sqrt(np.mean(err ** 2)) < 0.4 * noise and np.abs(err).max() < 2.0 * noise, err.std()
    assert np.all((uv >= 4.5) & (uv <= [94.5, 74.5]))      # inside the mask
    assert not np.any((uv[:, 0] > 60.5) & (uv[:, 0] < 73.5) & (uv[:, 1] > 20.5) & (uv[:, 1] < 28.5))  # not in the hole
    d = np.sort(np.linalg.norm(cloud[:, None, :2] - cloud[None, :, :2], axis=-1), axis=1)[:, 1]
    assert 0.25 * spacing < np.median(d) <= 1.05 * spacing
    assert cell_pixels(camera, spacing, 50.0) == 4
    step = noisy.copy()
    step[:, 50:] += 8.0                                     # an occluding edge through the cells at column 50
    cells = range_cloud(step, camera, 0.6, mask)            # 6 px cells: the edge cuts cells 48..53 in two
    uv, depth = camera.project(cells)
    truth = curved(*uv.T) + np.where(uv[:, 0] >= 50, 8.0, 0.0)
    assert np.abs(depth - truth).max() < 0.2, np.abs(depth - truth).max()   # no point between the surfaces
