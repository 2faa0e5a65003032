"""The 3D diagnosis of a cup holder's bottom (refine.solid, the paper's Sec. 4): the bottom slab and
its extruded hole morph, the cup's shape read off its mesh, bad input with clear errors, and (slow)
a hidden hole drawn under a seed found, a sound cup holder left alone, on data solved on a finer
mesh with noise (examples.cup_holder.synthetic), and the whole path from rendered intensity + range images
through ``nonrigid track --range`` to the diagnosis (examples.cup_holder.views)."""

import numpy as np
import pytest

import jaxfem as jf
from examples.cup_holder import cup_bottom, cup_holder
from refine.bundle.experiment import Experiment, MeshDomain
from refine.bundle.io import Bundle
from refine.bundle.observations import Forces, Observations
from refine.exceptions import ExperimentError, ObservationError
from refine.solid import MeshNotClosedError, check_closed, cup_shape
from refine.solid.loaded import moved_probe
from refine.solid.morph import ExtrudedMorph

R_IN, R_OUT, HEIGHT, BOTTOM = 8.0, 11.0, 8.0, 3.0


def test_extruded_hole_morph_moves_the_hole_through_the_thickness_and_the_probe_follows():
    hole = jf.Ellipse(1.0, -0.5, 2.5, 1.8, 0.4)
    slab = cup_bottom(R_IN, R_OUT, BOTTOM, 2.5, hole)
    mesh = slab.mesh
    assert mesh.element == "tet10" and mesh.jacobian_dets().min() > 0
    assert np.ptp(mesh.nodes[:, 2]) == pytest.approx(BOTTOM)
    # the z = 0 face: the disk minus the hole (polygonal: within 3 %)
    X, f = mesh.nodes, slab.facets
    area = 0.5 * np.linalg.norm(np.cross(X[f[:, 1]] - X[f[:, 0]], X[f[:, 2]] - X[f[:, 0]]), axis=1).sum()
    assert area == pytest.approx(np.pi * R_OUT**2 - hole.area, rel=0.03)
    morph = ExtrudedMorph.of(slab)
    np.testing.assert_allclose(morph(morph.params0), X, atol=1e-12)
    moved = np.array([[1.4, -0.2, 2.8, 2.0, 0.5]])
    Y = np.asarray(morph(moved))
    assert (mesh.jacobian_dets(Y) > 0).all()
    on = np.flatnonzero(np.linalg.norm(X[:, :2] - hole.to_curve(X[:, :2]), axis=1) < 1e-9)  # vertices on the hole
    new = jf.Ellipse(*moved[0])
    assert len(on) > 10 and np.abs(np.linalg.norm(Y[on, :2] - new.to_curve(Y[on, :2]), axis=1)).max() < 1e-9
    np.testing.assert_allclose(Y[:, 2], X[:, 2])  # through the thickness: z kept
    # a probe at fixed physical points follows the morph (each point keeps its cell): the moved
    # geometry maps back onto the points, and a field linear in the moved coordinates is exact
    rng = np.random.default_rng(0)
    pts = np.c_[rng.uniform(-9, 9, (60, 2)), rng.uniform(0.1, 2.9, 60)]
    pts = pts[(np.hypot(*pts[:, :2].T) < 10) & ~jf.Ellipse(1.4, -0.2, 3.2, 2.4, 0.5).contains(pts[:, :2])]
    probe = moved_probe(jf.locate(mesh, pts), Y, pts)
    np.testing.assert_allclose(probe(Y), pts, atol=1e-10)
    G = rng.normal(size=(3, 3))
    np.testing.assert_allclose(probe(Y @ G.T), pts @ G.T, atol=1e-10)
    assert not np.allclose(jf.locate(mesh, pts)(Y), pts, atol=1e-3)  # the unmoved probe would be wrong


def test_cup_shape_is_read_off_the_mesh_and_a_mesh_that_does_not_close_is_named():
    mesh = cup_holder(R_IN, R_OUT, HEIGHT, BOTTOM, 3.0).mesh
    moved = jf.Mesh(mesh.nodes + [5.0, -2.0, 1.0], mesh.cells, mesh.element)
    s = cup_shape(moved)
    assert s.centre == pytest.approx((5.0, -2.0), abs=0.01) and s.z0 == pytest.approx(1.0)
    assert (s.r_in, s.r_out, s.height, s.bottom) == pytest.approx((R_IN, R_OUT, HEIGHT, BOTTOM), abs=0.02)
    check_closed(mesh)
    # two blocks that touch along an edge only: four surface facets meet there
    a, b = jf.box(0, 0, 0, 1, 1, 1, 1, 1, 1, "tet4"), jf.box(1, 1, 0, 2, 2, 1, 1, 1, 1, "tet4")
    X, inv = np.unique(np.round(np.vstack([a.nodes, b.nodes]), 9), axis=0, return_inverse=True)
    cells = inv.reshape(-1)[np.vstack([a.cells, b.cells + a.n_nodes])]
    with pytest.raises(MeshNotClosedError, match="does not close"):
        check_closed(jf.Mesh(X, cells, "tet4"))


def hand_bundle(tmp_path, points, forces=True, nu=0.4):
    """A cup-holder bundle with zero displacements (no solve): bad-input checks stop before any."""
    jf.write_vtu(tmp_path / "mesh.vtu", cup_holder(R_IN, R_OUT, HEIGHT, BOTTOM, 3.0).mesh)
    n = len(points)
    r = np.hypot(*points[:, :2].T)
    roles = np.where(r > 7, "boundary", np.where(np.arange(n) % 3 == 0, "validate", "guide"))
    F = Forces(("back",), np.tile([[[0.0, 0.0, 1.0]]], (2, 1, 1))) if forces else None
    obs = Observations(np.arange(1, n + 1), points, roles, np.zeros((2, n, 3)), forces=F)
    exp = Experiment(name="cup", kind="solid", domain=MeshDomain("mesh.vtu"), law="neo-hookean", E=1.0, nu=nu)
    return Bundle(exp, obs, root=tmp_path)


def floor_points():
    g = np.arange(-9.5, 9.6, 1.5)
    xy = np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)
    xy = xy[np.hypot(*xy.T) < 10.5]
    return np.c_[xy, np.zeros(len(xy))]


def test_bad_input_is_named(tmp_path):
    from refine.solid.diagnose import SolidConfig, local_recipe

    pts = floor_points()
    shape, local, on = local_recipe(hand_bundle(tmp_path, pts), SolidConfig())
    assert on.all() and local.obs.n_points == len(pts) and local.force.shape == (2, 3)
    off = pts.copy()
    off[5] = [30.0, 0.0, 0.0]  # 19 mm off the cup
    with pytest.raises(ObservationError, match="not on the model.s surface.*point 6"):
        local_recipe(hand_bundle(tmp_path, off), SolidConfig())
    with pytest.raises(ObservationError, match="squeeze force.*back"):
        local_recipe(hand_bundle(tmp_path, pts, forces=False), SolidConfig())
    with pytest.raises(ExperimentError, match="nu must lie in"):
        hand_bundle(tmp_path, pts, nu=0.5)


def test_a_tracked_bundle_takes_the_load_cells_forces(tmp_path):
    from refine.bundle.io import read_bundle, write_bundle
    from examples.cup_holder.views import add_squeeze_forces

    root = write_bundle(tmp_path / "B", hand_bundle(tmp_path, floor_points(), forces=False))
    add_squeeze_forces(root, (0.0, 2.5))
    F = read_bundle(root).observations.forces
    assert F.edges == ("back",) and np.allclose(F.values[:, 0], [[0, 0, 0], [0, 0, 2.5]])


def run_cup(tmp_path, hole, seed):
    from refine.solid.write import diagnose_and_write
    from examples.cup_holder.synthetic import CupGeometry, write_cup_bundle

    root = write_cup_bundle(tmp_path / "cup", geometry=CupGeometry(), hole=hole, h_data=1.2, h_model=2.0,
                            noise=0.01, seed=seed)
    return diagnose_and_write(root, tmp_path / "out", quiet=True)


@pytest.mark.slow  # a finer 3D solve for the data and a 3D hole fit: minutes on 2 cores
def test_hidden_hole_in_the_bottom_is_found(tmp_path):
    from examples.cup_holder.synthetic import CupGeometry, random_hole

    hole = random_hole(CupGeometry(), 11)
    d, rep = run_cup(tmp_path, hole, 11)
    assert rep["cause"] == "hole", rep
    f = rep["findings"][0]
    # seed 11, a small hole (11.2 mm2), noise 0.01 mm, data at h 1.2 mm: area +17.6 % while the
    # global model's modulus was held (its discretisation stiffness enlarged the hole); noise-free
    # with the modulus fitted -0.9 %. With noise the area's standard error is 6-8 %
    # (benchmarks/diagnose3d.py: seeds 1-3 within 1.6 of it): the bounds allow about 3 of them
    assert np.hypot(f["centroid"][0] - hole.cx, f["centroid"][1] - hole.cy) < 0.02 * 22.0, (f, hole)
    assert f["area"] == pytest.approx(hole.area, rel=0.25), (f, hole)
    assert rep["held_out_gain"] > 1.2
    g = rep["global"]
    assert g["refined"]["validate_rms"] < g["initial"]["validate_rms"], g
    assert (tmp_path / "out" / "global" / "mesh.vtu").is_file()


@pytest.mark.slow
def test_sound_cup_holder_gives_no_finding(tmp_path):
    d, rep = run_cup(tmp_path, None, 4)
    assert rep["cause"] == "none" and rep["findings"] == [], rep


def track_and_diagnose(frames, camera, out, noise: float, nu: float, seed: int):
    """``nonrigid track --range`` of rendered frames, the load cell's forces added as forces.csv
    (side ``back``), then ``nonrigid diagnose``'s 3D diagnosis: the tracked bundle and the report."""
    from refine.bundle.from_tracks import ModelSkeleton
    from refine.bundle.io import read_bundle
    from refine.cli.track import track
    from refine.cli.track_range import RangeOptions
    from refine.solid.write import diagnose_and_write
    from examples.cup_holder.views import add_squeeze_forces

    model = ModelSkeleton(law="neo-hookean", E=1.0, nu=nu, noise_std=noise)  # kind "solid" from --range
    track(frames.images, out / "B", ranges=RangeOptions(frames.ranges, camera, frames.mesh), model=model,
          validate_fraction=1 / 3, seed=seed, quiet=True)
    add_squeeze_forces(out / "B", frames.forces)
    return read_bundle(out / "B"), diagnose_and_write(out / "B", out / "out", quiet=True)[1]


@pytest.mark.slow  # a 3D solve, rendering, tracking and the 3D diagnosis: minutes on 2 cores
def test_rendered_cup_holder_through_track_range_and_diagnose(tmp_path):
    from examples.cup_holder.synthetic import CupGeometry, random_hole
    from examples.cup_holder.views import CupScene, cup_camera, write_cup_frames

    hole = random_hole(CupGeometry(), 2)
    camera = cup_camera("orthographic", centre_px=(130.2, 120.4))  # the whole bottom in view
    scene = CupScene(hole=hole, camera=camera, shape=(240, 260), depth_noise=0.02, nu=0.4)
    frames = write_cup_frames(tmp_path / "frames", scene, forces=(1.0, 2.0, 3.0), h=1.2, seed=2)
    bundle, rep = track_and_diagnose(frames, camera, tmp_path, noise=0.01, nu=0.4, seed=2)
    assert bundle.experiment.kind == "solid" and bundle.observations.n_points > 150
    # benchmarks/diagnose3d.py's e2e row is this case: centre 0.53 % of the diameter, area -7.3 %
    # (its standard error 7.8 %), 223 s at load 9 (with the grid's edge evidence; before it 0.48 %,
    # -3.5 %, 352 s)
    assert rep["cause"] == "hole", rep
    f = rep["findings"][0]
    assert np.hypot(f["centroid"][0] - hole.cx, f["centroid"][1] - hole.cy) < 0.02 * 22.0, (f, hole)
    assert f["area"] == pytest.approx(hole.area, rel=0.1), (f, hole)


def test_hole_mesh_rule_sizes_the_hole_from_its_curvature_and_coarsens_with_h():
    """``Local.hole_h``: the element size along a hole's curve is the ratio times its smallest
    radius of curvature (b^2 / a), at most the floor's h; the coarser recipe (the discretisation
    error's refit) scales the hole's and the floor's sizes with h, so its mesh is coarser there too."""
    from refine.solid.local import Local

    rng = np.random.default_rng(7)
    a, b = rng.uniform(2.2, 2.8), rng.uniform(1.3, 1.6)
    hole = jf.Ellipse(*rng.uniform(-1, 1, 2), a, b, rng.uniform(0, np.pi))
    local = Local(None, None, None, None, 1.2, hole_ratio=0.5)
    assert local.hole_h(hole) == pytest.approx(0.5 * b * b / a)
    assert local.hole_h(None) is None and Local(None, None, None, None, 1.2).hole_h(hole) is None
    assert Local(None, None, None, None, 1.2, hole_ratio=5.0).hole_h(hole) == 1.2  # never above h
    coarse = Local(None, None, None, None, 1.2, hole_ratio=0.5, floor_h=0.9).coarser(1.2 * np.sqrt(2))
    assert coarse.h == pytest.approx(1.2 * np.sqrt(2)) and coarse.floor_h == pytest.approx(0.9 * np.sqrt(2))
    assert coarse.hole_h(hole) == pytest.approx(np.sqrt(2) * local.hole_h(hole))
