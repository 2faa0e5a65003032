"""The articulated hand (examples.hand, the paper's Sec. 5): mesh and named sets, joints that move
only their own degrees of freedom (rigid motions checked against SciPy's rotations), the soft
tissue's solve under a small thumb flexion, the strain threshold of a motion that changes speed at a
fraction drawn at random (found by refine.threshold through run_motion's detector hook, with the
maximum over the wrist's skin as the area of interest and a strain limit there), a scar drawn at
random on the wrist raising the maximum skin strain of a wrist motion and restricting it (slow),
bad input.

A coarse hand (no fingers, ~900 tet10 elements) keeps the fast tests at one compile;
benchmarks/hand.py runs the paper-size and a larger hand."""

from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import jaxfem as jf
from examples.hand import (Body, Bone, Box, HandModel, Joint, Motion, Scar, Tissues, bone_displacements,
                         default_body, hand_mesh, plot_curves, reachable, run_motion, scar_cells, skin_area,
                         write_motion_series)
from jaxfem.io import read_pvd
from refine.threshold import ThresholdRule
from tests._hand_util import COARSE, coarse_hand


@pytest.fixture(scope="module")
def hand():
    return coarse_hand()


@pytest.fixture(scope="module")
def model(hand):
    return HandModel(hand)


def descendants(body, name):
    out = {name}
    for b in body.bones:
        if b.parent in out:
            out.add(b.name)
    return out


def test_hand_mesh_and_sets(hand):
    mesh, X = hand.mesh, hand.mesh.nodes
    assert mesh.element == "tet10" and mesh.jacobian_dets().min() > 0
    boxes = hand.body.volumes.values()
    assert mesh.volumes().sum() == pytest.approx(sum(np.prod(np.subtract(b.hi, b.lo)) for b in boxes), rel=0.03)
    for k, bone in enumerate(hand.body.bones):
        nodes = hand.bone_nodes[bone.name]
        assert np.all(np.abs(X[nodes] - np.clip(X[nodes], bone.box.lo, bone.box.hi)) <= 4.5 + 1e-9)
        assert np.array_equal(nodes, np.unique(mesh.cells[mesh.regions == k + 1]))
    # skin: every boundary facet but the held cut, all outward; the cut is y = min of the forearm
    assert len(hand.skin_facets) + len(mesh.side_facets("bottom")) == len(mesh.boundary_facets())
    out = X[hand.skin_facets[:, :3]].mean(1) - mesh.centroids()[hand.skin_cells]
    assert np.all(np.einsum("fi,fi->f", out, hand.skin_normals()) > 0)  # normals point out of their cell
    assert np.allclose(X[hand.held_nodes, 1], X[:, 1].min())
    assert set(hand.marks) == {"thumb tip"}


@pytest.mark.parametrize("seed", [0, 1])
def test_each_joint_moves_only_its_degrees_of_freedom(hand, seed):
    rng = np.random.default_rng(seed)
    body, X = hand.body, hand.mesh.nodes
    for bone in body.bones[1:]:
        j = bone.joint
        angles = dict(zip(j.names, rng.uniform(-0.8, 0.8, len(j.names))))
        U = bone_displacements(hand, angles)
        moved = descendants(body, bone.name)
        R = Rotation.identity()
        for axis, name in zip(j.axes, j.names):  # first axis outermost
            R = R * Rotation.from_rotvec(np.asarray(axis) / np.linalg.norm(axis) * angles[name])
        p = np.asarray(j.pivot)
        for other, nodes in hand.bone_nodes.items():
            if other in moved:  # the bone and its children turn about the joint's pivot
                assert np.abs(X[nodes] + U[nodes] - (R.apply(X[nodes] - p) + p)).max() < 1e-10
            else:  # the forearm and every other bone stay where they are
                assert np.abs(U[nodes]).max() == 0.0
        if len(j.axes) == 1:  # a hinge: distances to its axis and positions along it are kept
            a = np.asarray(j.axes[0]) / np.linalg.norm(j.axes[0])
            nodes = hand.bone_nodes[bone.name]
            d0, d1 = X[nodes] - p, X[nodes] + U[nodes] - p
            assert np.abs(d0 @ a - d1 @ a).max() < 1e-10
            r0, r1 = np.linalg.norm(np.cross(d0, a), axis=1), np.linalg.norm(np.cross(d1, a), axis=1)
            assert np.abs(r0 - r1).max() < 1e-10
    assert np.abs(bone_displacements(hand, {"wrist_flexion": 0.5})[hand.held_nodes]).max() == 0.0


def test_small_thumb_flexion_solve_converges(model):
    hand = model.hand
    result = run_motion(model, Motion("thumb", {"thumb_1": 8.0, "thumb_2": 8.0}, "thumb tip", frames=1))
    assert not result.restricted and result.iterations[0] < 20
    u = result.u[-1]
    prescribed = bone_displacements(hand, {"thumb_1": np.radians(8.0), "thumb_2": np.radians(8.0)})
    for nodes in hand.bone_nodes.values():  # the bones' nodes move exactly as their rigid motions
        assert np.abs(u[nodes] - prescribed[nodes]).max() < 1e-10
    still = np.r_[hand.held_nodes, hand.bone_nodes["radius"], hand.bone_nodes["metacarpals"]]
    assert np.abs(u[still]).max() == 0.0  # the forearm (and the palm) stay fixed
    soft = np.setdiff1d(np.arange(hand.mesh.n_nodes), model.driven)
    assert np.abs(u[soft]).max() > 0.5  # the soft tissue follows the thumb (mm)
    assert hand.mesh.jacobian_dets(hand.mesh.nodes + u).min() > 0
    assert 0 < result.max_strain[-1] < 0.5 and result.displacement[-1] > 3.0


def random_wrist_scar(hand, seed):
    """A band-like scar across the palm side of the wrist: centre, semi-axes, angle and stiffness
    ratio drawn under ``seed`` (on this coarse mesh the wrist is two elements long, so the scar
    spans most of its width)."""
    rng = np.random.default_rng(seed)
    w = hand.body.volumes["wrist"]
    cy = 0.5 * (w.lo[1] + w.hi[1]) + rng.uniform(-3, 3)
    outline = jf.Ellipse(rng.uniform(-4, 4), cy, rng.uniform(18, 24), rng.uniform(8, 12), rng.uniform(-0.3, 0.3))
    return Scar(outline, depth=rng.uniform(7, 10), ratio=rng.uniform(3, 6))


def speed_change_schedule(frames, at, ratio):
    """Shares of the full range at frames 1..frames of a motion that moves ``ratio`` times faster
    after the share ``at`` of its duration than before (continuous, piecewise linear in time)."""
    t = np.arange(1, frames + 1) / frames
    slow = 1.0 / (at + ratio * (1 - at))
    return tuple(np.where(t <= at, slow * t, slow * (at + ratio * (t - at))))


@pytest.mark.parametrize("seed", [3])
def test_threshold_of_a_motion_that_changes_speed(model, seed):
    """The wrist turns slowly, then (from a random share of the motion's duration, drawn under the
    seed) 2-4 times faster: the wrist skin's maximum strain against time changes its growth rate
    there, and refine's detector, wired into run_motion's hook, finds it within 5 % of the motion."""
    rng = np.random.default_rng(seed)
    at, ratio = rng.uniform(0.35, 0.65), rng.uniform(2.0, 4.0)
    frames = 10
    motion = Motion("wrist up-down", {"wrist_flexion": rng.uniform(8.0, 12.0)}, "thumb tip", frames,
                    speed_change_schedule(frames, at, ratio))
    wrist = skin_area(model.hand, model.hand.body.volumes["wrist"])
    assert 0 < wrist.sum() < len(wrist)
    limit = 2e-3  # a stated strain limit over the area of interest, passed early in this motion
    r = run_motion(model, motion, area=wrist, against="time", strain_limit=limit,
                   detector=lambda x, s: ThresholdRule().find(x, s).to_json())
    assert len(r.time) == frames + 1 and np.all(r.area_max_strain <= r.max_strain + 1e-15)
    assert r.restricted and r.limited_by == "strain limit"  # the frames past it are still solved and kept
    assert r.reached == pytest.approx(reachable(r.fraction, r.area_max_strain, limit))
    t = r.threshold  # the one definition (refine.threshold.ThresholdRule.find): a threshold with its interval
    assert t["has_threshold"] and abs(t["fraction"] - at) < 0.05, (t, at)
    assert t["fraction_interval"][0] < t["fraction"] < t["fraction_interval"][1] and t["hinge"]["p_value"] < 1e-3
    assert t["hinge"]["rise"] > 1.5  # it speeds up
    with pytest.raises(jf.ProblemError, match="schedule"):
        Motion("bad", {"wrist_flexion": 5.0}, "thumb tip", 2, (0.6, 0.5))
    with pytest.raises(jf.ProblemError, match="area of interest"):
        skin_area(model.hand, Box((500.0, 500.0, 500.0), (501.0, 501.0, 501.0)))


@pytest.mark.slow  # two more wrist motions (~15 s): test_threshold_of_a_motion_that_changes_speed covers area and limit
def test_scar_raises_max_strain_of_wrist_motion_and_restricts_it(model, tmp_path):
    scar = random_wrist_scar(model.hand, 7)
    assert scar_cells(model.hand, scar).sum() >= 4
    motion = Motion("wrist up-down", {"wrist_flexion": 30.0}, "thumb tip", frames=1)
    # the area of interest of benchmarks/hand.py: the palm-side skin of wrist and forearm, |x| <= 16 mm (over
    # the wrist's whole skin this scar lowers the maximum: it lies in the stiff scar itself)
    wrist = skin_area(model.hand, Box((-16.0, -36.1, -20.0), (16.0, 0.1, -10.0)))
    normal = run_motion(model, motion, area=wrist)
    limit = 1.05 * normal.area_max_strain[-1]  # the stated limit: 5 % over the normal hand's full-range maximum
    scarred = run_motion(model, motion, scar=scar, strain_limit=limit, area=wrist,
                         detector=lambda d, s: (d[-1], s[-1]))
    assert scarred.area_max_strain[-1] > 1.05 * normal.area_max_strain[-1]
    assert scarred.restricted and scarred.limited_by == "strain limit" and 0.3 < scarred.reached < 1.0
    assert scarred.threshold == (scarred.displacement[-1], scarred.area_max_strain[-1])  # the detector hook
    vol, skin = write_motion_series(scarred, model.hand, tmp_path, E=model.moduli(scar)[0])
    assert len(read_pvd(vol)) == len(read_pvd(skin)) == 2
    assert plot_curves([normal, scarred], tmp_path / "curves.png").stat().st_size > 0


def test_bad_input():
    body = default_body(COARSE)
    b = body.bones[2]
    no_axis = replace(b, joint=replace(b.joint, axes=((0.0, 0.0, 0.0),)))
    with pytest.raises(jf.ProblemError, match="no axis"):
        replace(body, bones=body.bones[:2] + (no_axis,) + body.bones[3:])
    outside = replace(b, box=Box((60.0, 12.0, -4.0), (200.0, 20.0, 4.0)))
    with pytest.raises(jf.MeshError, match="not inside the body"):
        replace(body, bones=body.bones[:2] + (outside,) + body.bones[3:])
    with pytest.raises(jf.ProblemError, match="Poisson"):
        Tissues(nu_soft=0.5)
    with pytest.raises(jf.ProblemError, match="parent"):
        Body(body.volumes, (body.bones[0], Bone("x", b.box, "nowhere", b.joint)))
    with pytest.raises(jf.MeshError, match="positive"):
        hand_mesh(body, 0.0)
    with pytest.raises(jf.ProblemError, match="Joint|joint"):
        Body(body.volumes, (body.bones[0], replace(b, parent="radius", joint=Joint((0, 0, 0), ((1, 0, 0),), ()))))


def test_a_motion_newton_cannot_finish_is_restricted_where_it_stopped(model, monkeypatch):
    real, calls = model.solver.solve, []

    def fails_in_frame_two(theta, start=None):
        calls.append(1)
        if len(calls) == 2:
            raise jf.SolverError("no convergence", step=3, load_factor=0.5, reason="no-convergence")
        return real(theta, start)

    monkeypatch.setattr(model.solver, "solve", fails_in_frame_two)
    r = run_motion(model, Motion("wrist side-to-side", {"wrist_deviation": 6.0}, "thumb tip", frames=2))
    assert r.restricted and r.limited_by == "solver" and r.reached == pytest.approx(0.75)
    assert len(r.fraction) == 2 and r.max_strain[-1] > 0  # the frames reached are kept


@pytest.mark.slow  # a second compile (~15 s) and a thumb flexion with deformable bone ends
def test_deformable_bones_drive_their_middle_third(hand):
    model = HandModel(hand, Tissues(rigid_bones=False))
    assert len(model.driven) < len(np.unique(np.concatenate(list(hand.bone_nodes.values()))))
    r = run_motion(model, Motion("thumb", {"thumb_1": 8.0, "thumb_2": 8.0}, "thumb tip", frames=1))
    prescribed = bone_displacements(hand, {"thumb_1": np.radians(8.0), "thumb_2": np.radians(8.0)})
    free_bone = np.setdiff1d(hand.bone_nodes["thumb_2"], model.driven)
    assert np.abs(r.u[-1][model.driven] - prescribed[model.driven]).max() < 1e-10
    # the bone's free ends follow closely (17 MPa against 0.05 MPa soft tissue), not exactly
    err = np.abs(r.u[-1][free_bone] - prescribed[free_bone]).max()
    assert 0 < err < 0.05 * np.abs(prescribed[free_bone]).max()
