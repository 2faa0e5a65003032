"""``nonrigid track``: images -> measurement bundle (refine.cli.track; refine.bundle.from_tracks)."""

import argparse
import csv
import subprocess
import sys

import cv2
import numpy as np
import pytest

from refine.bundle.from_tracks import bundle_from_tracks, lattice_outline
from refine.cli.track import _tracker_options, add_parser, run as run_command
from refine.bundle.io import read_bundle
from refine.bundle.experiment import PolygonDomain, RectangleDomain
from tracking import render_grid, render_speckle, scaled, smooth_displacement, track_images

SHAPE = (200, 300)  # rows, cols
PITCH = 12.0
SCALE = 0.5  # mm/px
ROI = (30, 30, 270, 170)
OCCLUDED = (slice(80, 115), slice(140, 175))  # rows, cols painted over in the last frame


def parse(*argv):
    parser = argparse.ArgumentParser(prog="nonrigid")
    add_parser(parser.add_subparsers(dest="command"))
    return parser.parse_args(["track", *map(str, argv)])


def run(*argv):
    return run_command(parse(*argv))


def write_png(path, image):
    cv2.imwrite(str(path), np.clip(np.rint(image), 0, 255).astype(np.uint8))
    return path


@pytest.fixture(scope="module")
def grid_images(tmp_path_factory):
    """Three 300 x 200 px frames of a stretched grid (pitch 12 px); a patch of the last one is
    painted over, so the crossings under it are lost."""
    folder = tmp_path_factory.mktemp("grid")
    field = smooth_displacement(SHAPE, stretch=0.06, seed=1)
    paths = []
    for k in range(3):
        image = render_grid(SHAPE, PITCH, 2.0, None if k == 0 else scaled(field, k / 2), noise_sigma=2.0, seed=k)
        if k == 2:
            image[OCCLUDED] = 200.0
        paths.append(write_png(folder / f"frame{k}.png", image))
    return paths, field


@pytest.fixture(scope="module")
def tracked(grid_images, tmp_path_factory):
    paths, field = grid_images
    out = tmp_path_factory.mktemp("bundle") / "sheet"
    args = parse("--pattern", "grid", "--scale", SCALE, "--roi", ",".join(map(str, ROI)), *paths, "--out", out,
                 "--E", 2.5, "--nu", 0.25, "--validate-fraction", 0.25, "--seed", 3)
    assert run_command(args) == 0
    tracks = track_images(paths, "grid", roi=ROI)
    return out, tracks, field


def test_bundle_reads_back_with_the_tracker_ids_and_image_axes_in_mm(tracked, capsys):
    out, tracks, field = tracked
    bundle = read_bundle(out)
    obs = bundle.observations
    assert obs.n_frames == 2 and obs.n_points == tracks.n_points
    np.testing.assert_array_equal(obs.ids, tracks.ids)
    np.testing.assert_allclose(obs.reference, tracks.reference * SCALE, atol=1e-9)  # x = col * scale
    np.testing.assert_allclose(obs.displacements, tracks.displacements()[1:] * SCALE, atol=1e-9)
    # frames in the order given: the last image is the full stretch, the middle one half of it
    truth = np.stack(field(*tracks.reference.T), axis=1) * SCALE
    ok = np.isfinite(obs.displacements[1]).all(axis=1)
    # a crossing whose line profiles reach into the painted-over patch (within half a pitch of it)
    # is measured on a half-occluded line: not what this check is about
    rows, cols = OCCLUDED
    x, y = tracks.reference.T
    near = ((x > cols.start - PITCH / 2) & (x < cols.stop + PITCH / 2)
            & (y > rows.start - PITCH / 2) & (y < rows.stop + PITCH / 2))
    assert np.abs(obs.displacements[1, ok & ~near] - truth[ok & ~near]).max() < 0.05
    assert np.abs(obs.displacements[0] - 0.5 * truth).max() < 0.05
    roles = dict(zip(*np.unique(obs.roles, return_counts=True)))
    assert roles["boundary"] == 2 * (20 + 11) - 4  # the outer ring of a 20 x 11 lattice
    assert roles["validate"] == round(0.25 * (tracks.n_points - roles["boundary"]))
    ex = bundle.experiment
    assert (ex.kind, ex.law, ex.E, ex.nu, ex.noise_std) == ("plane-stress", "neo-hookean", 2.5, 0.25, None)
    assert ex.units["length"] == "mm"
    assert "CHECK" in (out / "experiment.toml").read_text()


def test_ids_are_the_same_in_every_file_every_frame_and_every_run(tracked, grid_images, tmp_path):
    out, tracks, _ = tracked
    paths, _ = grid_images
    assert run("--scale", SCALE, "--roi", ",".join(map(str, ROI)), *paths, "--out", tmp_path / "again",
               "--validate-fraction", 0.25, "--seed", 3) == 0
    for name in ("points.csv", "displacements.csv"):
        assert (tmp_path / "again" / name).read_text() == (out / name).read_text()
    with open(out / "points.csv") as f:
        ids = [int(row["id"]) for row in csv.DictReader(f)]
    with open(out / "displacements.csv") as f:
        rows = list(csv.DictReader(f))
    for frame in ("1", "2"):
        assert [int(r["id"]) for r in rows if r["frame"] == frame] == ids
    assert len(set(ids)) == len(ids)


def test_boundary_points_lie_on_the_domain_outline_and_the_rest_inside(tracked):
    out, _, _ = tracked
    bundle = read_bundle(out)
    domain, obs = bundle.experiment.domain, bundle.observations
    assert isinstance(domain, RectangleDomain)
    x, y = obs.reference.T
    to_edge = np.min([x - domain.xmin, domain.xmax - x, y - domain.ymin, domain.ymax - y], axis=0)
    spacing = PITCH * SCALE
    assert to_edge.min() >= 0  # every point is in the domain
    boundary = obs.roles == "boundary"
    assert to_edge[boundary].max() < 0.02 * spacing
    assert to_edge[~boundary].min() > 0.9 * spacing


def test_lost_points_are_written_as_empty_cells(tracked):
    out, tracks, _ = tracked
    lost = tracks.lost[2]
    assert 4 <= lost.sum() <= 16 and not tracks.lost[1].any()
    under = tracks.reference[lost]  # the painted-over patch hid them
    assert np.all((under[:, 0] > 135) & (under[:, 0] < 180) & (under[:, 1] > 75) & (under[:, 1] < 120))
    with open(out / "displacements.csv") as f:
        rows = {(r["frame"], int(r["id"])): (r["ux"], r["uy"]) for r in csv.DictReader(f)}
    for pid in tracks.ids[lost]:
        assert rows["2", pid] == ("", "") and rows["1", pid] != ("", "")
    assert np.isnan(read_bundle(out).observations.displacements[1, lost]).all()


def test_an_overlay_per_frame_is_written(tracked):
    out, _, _ = tracked
    for k in range(3):
        image = cv2.imread(str(out / "overlays" / f"frame_{k:03d}.png"))
        assert image is not None and image.shape[0] > SHAPE[0] and image.shape[1] > SHAPE[1]
    last = cv2.imread(str(out / "overlays" / "frame_002.png")).astype(int)
    reddish = (last[..., 2] > 200) & (last[..., 1] < 60) & (last[..., 0] < 60)
    assert reddish.sum() > 20  # the lost points' red crosses


def test_the_summary_says_points_frames_and_lost_per_frame(grid_images, tmp_path, capsys):
    paths, _ = grid_images
    assert run("--scale", SCALE, "--roi", "60,50,200,140", *paths, "--out", tmp_path / "b") == 0
    text = capsys.readouterr().out
    assert "tracked" in text and "3 images" in text and "lost per frame: 0:0 1:0 2:" in text


def test_the_nonrigid_command_line_runs_track(grid_images, tmp_path):
    paths, _ = grid_images
    command = [sys.executable, "-m", "refine.cli", "track", "--scale", str(SCALE), "--roi", "60,50,200,140",
               *map(str, paths[:2]), "--out", str(tmp_path / "b")]
    done = subprocess.run(command, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert read_bundle(tmp_path / "b").observations.n_frames == 1
    command[command.index("60,50,200,140")] = "60,50,400,140"
    done = subprocess.run(command, capture_output=True, text=True, timeout=600)
    assert done.returncode == 2 and "nonrigid track: error:" in done.stderr and "outside the image" in done.stderr


def test_grid_pitch_gives_the_scale(grid_images, tmp_path):
    paths, _ = grid_images
    assert run("--grid-pitch", 6.0, "--roi", ",".join(map(str, ROI)), *paths, "--out", tmp_path / "b") == 0
    ref = read_bundle(tmp_path / "b").observations.reference
    tracks = track_images(paths[:1], "grid", roi=ROI)
    np.testing.assert_allclose(ref, tracks.reference * SCALE, rtol=2e-3)


def test_origin_shifts_the_coordinates(grid_images, tmp_path):
    paths, _ = grid_images
    assert run("--scale", 1.0, "--origin", "30,20", "--roi", ",".join(map(str, ROI)), *paths[:2],
               "--out", tmp_path / "b") == 0
    ref = read_bundle(tmp_path / "b").observations.reference
    tracks = track_images(paths[:1], "grid", roi=ROI)
    np.testing.assert_allclose(ref, tracks.reference - [30, 20], atol=1e-9)


def test_speckle_images_and_tracker_options(tmp_path):
    shape = (120, 160)
    field = smooth_displacement(shape, stretch=0.03, seed=2, waviness=0.2)
    paths = [write_png(tmp_path / f"s{k}.png", render_speckle(shape, 1.5, None if k == 0 else scaled(field, k / 2),
                                                                 noise_sigma=1.0, seed=k)) for k in range(3)]
    assert run("--pattern", "speckle", "--scale", 0.1, "--spacing", 12, "--subset", 21, *paths,
               "--out", tmp_path / "b", "--noise-std", 0.003, "--kind", "plane-strain") == 0
    bundle = read_bundle(tmp_path / "b")
    obs = bundle.observations
    assert bundle.experiment.noise_std == 0.003 and bundle.experiment.kind == "plane-strain"
    assert bundle.experiment.subset == pytest.approx(2.1)  # the 21 px subset at 0.1 mm/px (measurement.subset)
    assert np.allclose(np.diff(np.unique(obs.reference[:, 0])), 1.2)  # 12 px lattice at 0.1 mm/px
    truth = np.stack(field(*(obs.reference / 0.1).T), axis=1) * 0.1
    assert np.nanmax(np.abs(obs.displacements[1] - truth)) < 0.01


@pytest.mark.parametrize("argv, message", [
    (["--scale", 0.5, "--roi", "100,50,400,150"], "outside the image"),
    (["--scale", 0.5, "--roi", "10,20,30"], "--roi X0,Y0,X1,Y1 takes 4 numbers"),
    (["--roi", "30,30,270,170"], "give the image scale: --scale"),
    (["--scale", 0.5, "--noise-std", "-1"], "--noise-std takes 'auto' or a positive number"),
    (["--pattern", "speckle", "--grid-pitch", 2.0], "--grid-pitch needs --pattern grid"),
    (["--scale", 0.5, "--subset", 21], "unknown option(s) ['subset'] for pattern 'grid'"),
    (["--scale", -0.5], "--scale must be a positive number"),
    (["--scale", 0.5, "--nu", 0.6], "material.nu must lie in (-1, 0.5)"),
])
def test_bad_command_lines_fail_with_a_clear_message(grid_images, tmp_path, capsys, argv, message):
    paths, _ = grid_images
    assert run(*argv, *paths[:2], "--out", tmp_path / "b") == 2
    err = capsys.readouterr().err
    assert err.startswith("nonrigid track: error:") and message in err
    assert not (tmp_path / "b").exists()


def test_unreadable_or_missing_images_fail_with_a_clear_message(grid_images, tmp_path, capsys):
    paths, _ = grid_images
    broken = tmp_path / "broken.png"
    broken.write_text("not an image")
    assert run("--scale", 0.5, paths[0], broken, "--out", tmp_path / "b") == 2
    assert f"cannot read image {broken}" in capsys.readouterr().err
    assert run("--scale", 0.5, paths[0], tmp_path / "missing.png", "--out", tmp_path / "b") == 2
    assert "image file not found" in capsys.readouterr().err
    assert run("--scale", 0.5, paths[0], "--out", tmp_path / "b") == 2
    assert "at least two images" in capsys.readouterr().err


def test_outline_of_a_lattice_with_a_notch_and_a_single_corner_contact():
    # a 4 x 4 lattice without its 2 x 2 corner (i < 2, j >= 2), and a square touching it at (3, 3) only
    cells = [(i, j) for i in range(4) for j in range(4) if not (i < 2 and j >= 2)] + [(3, 4), (4, 3), (4, 4)]
    index = np.array(cells)
    loop = [tuple(int(v) for v in index[k]) for k in lattice_outline(index)]
    assert len(loop) == len(set(loop)) == 12  # every outline point once, the touching square left out
    expected = {(0, 0), (0, 1), (1, 1), (2, 1), (2, 2), (2, 3), (3, 3), (3, 2), (3, 1), (3, 0), (2, 0), (1, 0)}
    assert set(loop) == expected
    steps = np.abs(np.diff(np.array(loop + loop[:1]), axis=0)).sum(axis=1)
    assert np.all(steps == 1)  # in order around it


def test_a_rotated_grid_gets_a_polygon_through_its_outer_ring(tmp_path):
    shape = (160, 200)
    images = [render_grid(shape, 12.0, 2.0, None, angle_deg=12.0, noise_sigma=1.0, seed=k) for k in range(2)]
    tracks = track_images(images, "grid", roi=(20, 20, 180, 140)).to_length(0.5)
    bundle, dropped = bundle_from_tracks(tracks, "rotated")
    domain, obs = bundle.experiment.domain, bundle.observations
    assert isinstance(domain, PolygonDomain)
    # points that belong to no cell of the lattice (corners of the staircase) are left out
    assert obs.n_points + dropped.size == tracks.n_points
    occupied = {tuple(ij) for ij in tracks.grid_index.tolist()}
    for i, j in tracks.grid_index[np.isin(tracks.ids, dropped)].tolist():
        assert not any(all((i + a + da, j + b + db) in occupied for da in (0, 1) for db in (0, 1))
                       for a in (-1, 0) for b in (-1, 0))
    vertices = np.array(domain.vertices)
    x, y = vertices.T
    assert np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)) > 0  # counter-clockwise
    boundary = obs.reference[obs.roles == "boundary"]
    assert len(boundary) == len(vertices)
    assert np.abs(boundary[:, None] - vertices[None]).sum(-1).min(axis=1).max() < 1e-12


def test_line_shape_flag_reaches_the_grid_tracker_and_is_refused_for_speckle():
    parser = argparse.ArgumentParser()
    add_parser(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["track", "a.png", "b.png", "--out", "x", "--scale", "0.5", "--line-shape", "curved"])
    assert _tracker_options(args)["line_shape"] == "curved"
    with pytest.raises(SystemExit):  # argparse names the allowed shapes
        parser.parse_args(["track", "a.png", "--out", "x", "--scale", "0.5", "--line-shape", "wavy"])
    from tracking import TrackingError

    frames = np.zeros((2, 32, 32))
    with pytest.raises(TrackingError, match="line_shape"):
        track_images(frames, "speckle", line_shape="curved")
