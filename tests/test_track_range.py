"""``nonrigid track --range``: a cup holder's bottom rendered (a grid painted in reference coordinates,
intensity + range images with depth noise, part of it out of view) and tracked into a 3D bundle;
range holes give lost points with their reason; ``--clouds-only`` gives clouds on the surface.

The motion here is a smooth analytic bulge of random size (seeded) on a cup-holder mesh, so the test
stays fast; tests/test_cup_holder_range.py (slow) renders a solved compression."""

import csv

import cv2
import numpy as np
import pytest

import jaxfem as jf
import tracking
from refine.bundle.io import read_bundle
from refine.cli.main import main
from examples.cup_holder.views import CupScene, painted_crossings, render_cup
from examples.synthetic.solid_render import surface_distance

NOISE = 0.05  # mm, range noise (structured light)


def bulge(X, amplitude, seed):
    """A smooth push of the bottom into the cup (up to ``amplitude`` mm) with a random in-plane stretch."""
    rng = np.random.default_rng(seed)
    sx, sy = rng.uniform(-0.02, 0.02, 2)
    r2 = (X[:, 0] ** 2 + X[:, 1] ** 2) / 11.0 ** 2
    return np.c_[sx * amplitude * X[:, 0], sy * amplitude * X[:, 1], amplitude * (1 - r2) * np.exp(-X[:, 2] / 3)]


@pytest.fixture(scope="module")
def scene_files(tmp_path_factory):
    root = tmp_path_factory.mktemp("cup_range")
    rng = np.random.default_rng(2)
    scene = CupScene(depth_noise=NOISE)
    cup = scene.mesh(2.5)                          # the rendering's mesh; the bundle gets a coarser one
    top = rng.uniform(0.5, 1.0)
    U = [bulge(cup.mesh.nodes, a * top, 3) for a in (0.5, 1.0)]
    views = render_cup(scene, cup, U, seed=4)
    truth = painted_crossings(scene, cup, U)
    # holes in the scans: one in the reference frame (its points have no reference position) and one
    # in frame 1 (its points are lost there), each over a random painted crossing in view
    uv, _ = scene.camera.project(truth[0])
    inside = np.flatnonzero((uv[:, 0] > 30) & (uv[:, 0] < 210) & (uv[:, 1] > 30) & (uv[:, 1] < 170))
    holes = rng.choice(inside, 2, replace=False)
    for frame, k in zip((0, 1), holes):
        u, v = scene.camera.project(truth[frame][k])[0]
        yy, xx = np.mgrid[0:scene.shape[0], 0:scene.shape[1]]
        views[frame].range[(xx - u) ** 2 + (yy - v) ** 2 < 2.5 ** 2] = np.nan
    for k, view in enumerate(views):
        cv2.imwrite(str(root / f"img_{k}.png"), np.clip(np.rint(view.image), 0, 255).astype(np.uint8))
        np.save(root / f"range_{k}.npy", view.range.astype(np.float32))
    jf.write_vtu(root / "cup.vtu", scene.mesh(3.0).mesh)
    (root / "camera.toml").write_text(_toml(scene.camera.to_toml()))
    return root, scene, views, truth, holes, (cup, U)


def _toml(table):
    import tomli_w

    return tomli_w.dumps(table)


def _track(root, out, *extra):
    return main(["track", *[str(root / f"img_{k}.png") for k in range(3)], "--range",
                 *[str(root / f"range_{k}.npy") for k in range(3)], "--mesh", str(root / "cup.vtu"),
                 "--camera", str(root / "camera.toml"), "--out", str(out), *extra])


@pytest.fixture(scope="module")
def tracked(scene_files, tmp_path_factory):
    out = tmp_path_factory.mktemp("tracked") / "B"
    assert _track(scene_files[0], out) == 0
    return out


def test_rendered_cup_holder_tracked_in_3d_within_the_depth_noise(scene_files, tracked):
    root, scene, views, truth, holes, _ = scene_files
    bundle = read_bundle(tracked)
    exp, obs = bundle.experiment, bundle.observations
    assert exp.kind == "solid" and exp.domain.path == "cup.vtu" and (tracked / "cup.vtu").is_file()
    assert obs.dim == 3 and obs.n_points > 120 and set(obs.roles) == {"boundary", "guide", "validate"}
    from scipy.spatial import cKDTree

    dist, match = cKDTree(truth[0]).query(obs.reference)
    assert dist.max() < 0.3 * scene.paint.pitch                 # every point is a painted crossing
    ref_err = obs.reference - truth[0][match]
    # in-plane: the grid tracker's ~0.05 px (0.005 mm); depth: the bilinear mean of 4 noisy pixels.
    # A crossing whose arms reach the cup's silhouette (within a pixel of half the 12.5 px pitch)
    # sees a cut line in a frame the bulge moved unlike the reference's affine map: 0.3 px there
    from scipy import ndimage

    body = ndimage.distance_transform_edt(ndimage.binary_fill_holes(np.isfinite(views[0].range)))
    uv, _ = scene.camera.project(obs.reference)
    rim = body[np.rint(uv[:, 1]).astype(int), np.rint(uv[:, 0]).astype(int)] < 0.5 * 12.5 + 1.5
    bound = np.where(rim, 0.03, 0.015)
    assert np.count_nonzero(rim) <= 0.05 * obs.n_points
    assert (np.abs(ref_err[:, :2]).max(axis=1) < bound).all(), np.abs(ref_err[:, :2]).max()
    assert np.sqrt(np.mean(ref_err[:, 2] ** 2)) < 0.8 * NOISE and np.abs(ref_err[:, 2]).max() < 4 * NOISE
    for f in range(2):
        ok = np.isfinite(obs.displacements[f]).all(axis=1)
        err = obs.reference[ok] + obs.displacements[f][ok] - truth[f + 1][match[ok]]
        assert np.sqrt(np.mean(err[:, 2] ** 2)) < 0.8 * NOISE
        assert (np.abs(err[:, :2]).max(axis=1) < bound[ok]).all(), np.abs(err[:, :2]).max()
        moved = np.abs(truth[f + 1][match[ok], 2] - truth[0][match[ok], 2]).max()
        assert moved > 5 * NOISE                                 # the motion is well above the noise


def test_a_wider_range_window_averages_more_depth_noise(scene_files, tracked, tmp_path, capsys):
    root, scene, views, truth, holes, _ = scene_files
    from scipy.spatial import cKDTree

    def depth_rms(bundle_root):
        obs = read_bundle(bundle_root).observations
        _, match = cKDTree(truth[0]).query(obs.reference)
        pos = np.concatenate([obs.reference[None], obs.reference[None] + obs.displacements])
        err = [p[np.isfinite(p).all(axis=1), 2] - t[match[np.isfinite(p).all(axis=1)], 2] for p, t in zip(pos, truth)]
        return np.sqrt(np.mean(np.concatenate(err) ** 2)), obs.n_points

    assert _track(root, tmp_path / "B", "--range-radius", "4") == 0  # 9 x 9 pixels, inside the 12.5 px pitch
    (rms5, n5), (rms9, n9) = depth_rms(tracked), depth_rms(tmp_path / "B")
    # a least-squares quadratic's noise at its centre: sqrt(6 / 81) against sqrt(6 / 25) of the noise
    assert rms9 < 0.7 * rms5 and rms9 < 0.25 * NOISE and n9 >= n5 - 2, (rms5, rms9, n5, n9)
    assert _track(root, tmp_path / "C", "--range-radius", "0") == 2
    assert "--range-radius must be a whole number of pixels >= 1, got 0" in capsys.readouterr().err


def test_range_holes_give_lost_points_with_their_reason(scene_files, tracked):
    root, scene, views, truth, holes, _ = scene_files
    obs = read_bundle(tracked).observations
    rows = list(csv.DictReader(open(tracked / "lost.csv")))
    no_range = tracking.LOST_REASONS[8]
    frame0 = {int(r["id"]) for r in rows if r["frame"] == "0" and r["reason"] == no_range}
    assert frame0 and not frame0 & set(obs.ids.tolist())        # left out of points.csv, listed in lost.csv
    assert {r["reason"] for r in rows if r["frame"] != "0" and int(r["id"]) in frame0} <= {
        tracking.LOST_REASONS[11], no_range}
    frame1 = {int(r["id"]) for r in rows if r["frame"] == "1" and r["reason"] == no_range} - frame0
    assert frame1
    lost1 = set(obs.ids[np.isnan(obs.displacements[0]).any(axis=1)].tolist())
    assert frame1 <= lost1                                      # lost in frame 1 ...
    found2 = set(obs.ids[np.isfinite(obs.displacements[1]).all(axis=1)].tolist())
    assert frame1 <= found2                                     # ... and measured again in frame 2
    # the lost points are those near the holes' centres (within the hole's radius + 1 px)
    uv0, _ = scene.camera.project(truth[0][holes[0]])
    centre = scene.camera.to_world(uv0, np.array(60.0))[:2]
    ids_xy = {int(r["id"]): (float(r["u"]), float(r["v"])) for r in rows if r["frame"] == "0" and r["u"]}
    for i in frame0:
        assert np.hypot(*(np.array(ids_xy[i]) - uv0)) < 4.0, (i, ids_xy[i], uv0, centre)


def test_a_frame_without_range_and_bad_range_options_are_clear_errors(scene_files, tmp_path, capsys):
    root, *_ = scene_files
    np.save(tmp_path / "empty.npy", np.full((200, 240), np.nan, np.float32))
    argv = ["track", *[str(root / f"img_{k}.png") for k in range(3)], "--mesh", str(root / "cup.vtu"), "--scale", "0.1",
            "--out", str(tmp_path / "B"), "--range"]
    assert main(argv + [str(root / "range_0.npy"), str(tmp_path / "empty.npy"), str(root / "range_2.npy")]) == 2
    assert "empty.npy (frame 1) has no range data" in capsys.readouterr().err
    assert main(argv + [str(root / "range_0.npy"), str(root / "range_1.npy")]) == 2
    assert "3 images but 2 range images" in capsys.readouterr().err
    no_mesh = [a for a in argv if a not in ("--mesh", str(root / "cup.vtu"))]
    assert main(no_mesh + [str(root / f"range_{k}.npy") for k in range(3)]) == 2
    assert "needs the body's mesh: give --mesh" in capsys.readouterr().err
    assert main(argv[:-1] + ["--fx", "600", "--range", *[str(root / f"range_{k}.npy") for k in range(3)]]) == 2
    assert "needs all of --fx --fy --cx --cy" in capsys.readouterr().err


def test_clouds_only_lie_on_the_true_surface_within_the_noise(scene_files, tmp_path):
    root, scene, views, truth, holes, (cup, U) = scene_files
    out = tmp_path / "C"
    assert main(["track", "--clouds-only", "--range", *[str(root / f"range_{k}.npy") for k in range(3)],
                 "--mesh", str(root / "cup.vtu"), "--camera", str(root / "camera.toml"), "--out", str(out),
                 "--cloud-spacing", "0.4", "--roi", "20,10,230,190"]) == 0
    bundle = read_bundle(out)
    assert bundle.observations is None and bundle.clouds.n_frames == 2 and bundle.experiment.kind == "solid"
    for k, (cloud, u) in enumerate(zip(bundle.clouds.points, [None, *U])):
        uv, depth = scene.camera.project(cloud)
        assert np.all((uv >= [19.5, 9.5]) & (uv <= [230.5, 190.5])) and len(cloud) > 1000
        distance = surface_distance(cloud, cup.mesh.nodes, cup.mesh.boundary_facets(), u)
        # 16 pixels per point: ~noise / 4 (measured 0.013 mm RMS); a cell on the bottom's silhouette
        # may hold a single pixel: its full noise (measured at most 0.10 mm, 2 noise)
        assert np.sqrt(np.mean(distance ** 2)) < 0.4 * NOISE and distance.max() < 3 * NOISE, (k, distance.max())
    mask = np.zeros(scene.shape, np.uint8)
    mask[:, 120:] = 255                                         # a drawn mask: the right half only
    cv2.imwrite(str(tmp_path / "mask.png"), mask)
    assert main(["track", "--clouds-only", "--range", *[str(root / f"range_{k}.npy") for k in range(3)],
                 "--mesh", str(root / "cup.vtu"), "--scale", "0.1", "--origin", "85.3,100.2", "--out",
                 str(tmp_path / "M"), "--mask", str(tmp_path / "mask.png")]) == 0
    half = read_bundle(tmp_path / "M").clouds.points[0]
    assert half[:, 0].min() > (119.5 - 85.3) * 0.1 and len(half) > 300   # default spacing: 3 px = 0.3 mm


def test_speckle_subset_centres_are_looked_up_in_3d(tmp_path):
    """Subset centres of a speckle pattern on a tilted plane that moves: each centre's depth is the
    plane's at its tracked position in its own frame (orthographic camera from the flags)."""
    shape = (120, 140)
    u = tracking.smooth_displacement(shape, stretch=0.04, seed=3)
    plane = [lambda x, y, k=k: 40.0 + 0.02 * x + 0.01 * y + 0.3 * k for k in range(3)]   # moves 0.3 mm per frame
    for k, frac in enumerate((0.0, 0.5, 1.0)):
        image = tracking.render_speckle(shape, 1.2, tracking.scaled(u, frac) if frac else None, seed=k, noise_sigma=1.0)
        cv2.imwrite(str(tmp_path / f"s_{k}.png"), np.clip(np.rint(image), 0, 255).astype(np.uint8))
        np.save(tmp_path / f"z_{k}.npy", tracking.render_range(plane[k], shape, noise_sigma=0.0))
    jf.write_vtu(tmp_path / "m.vtu", jf.box(0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1, 1, 1, "tet4"))
    assert main(["track", *[str(tmp_path / f"s_{k}.png") for k in range(3)], "--pattern", "speckle",
                 "--range", *[str(tmp_path / f"z_{k}.npy") for k in range(3)], "--mesh", str(tmp_path / "m.vtu"),
                 "--scale", "0.1", "--origin", "70,60", "--out", str(tmp_path / "B"), "--spacing", "12",
                 "--subset", "21", "--range-order", "1"]) == 0
    obs = read_bundle(tmp_path / "B").observations
    assert obs.n_points > 20
    for k in range(3):
        xyz = obs.reference + (obs.displacements[k - 1] if k else 0.0)
        ok = np.isfinite(xyz).all(axis=1)
        col, row = xyz[ok, 0] / 0.1 + 70, xyz[ok, 1] / 0.1 + 60
        np.testing.assert_allclose(xyz[ok, 2], plane[k](col, row), atol=1e-6)   # bilinear is exact on a plane
    truth = tracking.deformed_points(obs.reference[:, :2] / 0.1 + [70, 60], u)              # frame 2, px
    error = np.abs((obs.reference[:, :2] + obs.displacements[1, :, :2]) / 0.1 + [70, 60] - truth)
    found = np.isfinite(error).all(axis=1)
    assert found.sum() > 0.8 * obs.n_points and error[found].max() < 0.1
