"""Tracking the hand (examples.hand, the paper's Sec. 5 with issue 25's item 5): the kinematic
Dirichlet data differentiable in the joint angles, the tracker's exact Jacobian (Taylor test
through the solve), a strain map carried between hand meshes, bad input (no data, an empty range
frame, a cloud far from the hand, markers off it, unknown angles), restarts and the
constant-velocity start, a hand mesh refined along the thumb, and (slow) joint angles recovered
within a degree from range sequences and markers (from the markers alone: within the reported
uncertainty) generated on a finer mesh with noise (examples.hand.range) by the default
tracking model (refined along the thumb) and smoothed over the sequence (examples.hand.smooth;
tests/test_hand_track_smooth.py tests the smoother), angles and pose drawn under three seeds.

A coarse hand (no fingers, ~900 tet10 elements, as tests/test_hand.py) keeps the fast tests at one
compile; benchmarks/hand.py tracks the paper-size hand."""


import functools
from dataclasses import replace

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from examples.hand import HandModel, along, bone_displacements, default_body, hand_mesh
from refine.exceptions import CorrespondenceError
from examples.hand import (FrameFit, HandTracker, TrackConfig, angle_errors, error_chi2, skin_strain_on, smooth,
                         tracking_model)
from examples.hand.range import hand_range_sequence, pose_matrix
from tests._hand_util import coarse_hand


@pytest.fixture(scope="module")
def hand():
    return coarse_hand()


@pytest.fixture(scope="module")
def tracker(hand):
    return HandTracker(HandModel(hand), TrackConfig(max_points=200))


@pytest.mark.parametrize("seed", [0, 1])
def test_kinematic_data_is_differentiable_in_the_angles(hand, tracker, seed):
    rng = np.random.default_rng(seed)
    model = tracker.model
    names = hand.body.angle_names
    a = rng.uniform(-0.6, 0.6, len(names))
    u_D = np.asarray(model.drive(dict(zip(names, a))))
    assert np.allclose(u_D, model.params(dict(zip(names, a)))["u_D"], atol=1e-12)
    assert np.allclose(u_D, bone_displacements(hand, dict(zip(names, a))).reshape(-1)[model.problem.fixed])
    f = jax.jit(lambda v: model.drive(dict(zip(names, v))))
    J = np.asarray(jax.jit(jax.jacfwd(f))(jnp.asarray(a)))
    d = rng.normal(size=len(names))
    for eps in (1e-3, 5e-4):  # Taylor: the remainder falls as eps^2
        rem = np.linalg.norm(np.asarray(f(a + eps * d)) - u_D - eps * J @ d)
        assert rem < 2e-3 * eps * np.linalg.norm(J @ d)
    assert np.abs(J).max() > 1.0  # the angles move the bones (mm per radian)


def test_tracker_jacobian_passes_a_taylor_test(hand, tracker):
    """Residuals of a cloud on the skin and of markers at random angles and pose: the exact
    Jacobian (through the solve) against the residuals' change along a random direction."""
    rng = np.random.default_rng(3)
    names = tracker.names
    q = np.r_[rng.uniform(-0.03, 0.03, 3), rng.uniform(-2, 2, 3), rng.uniform(-0.15, 0.15, len(names))]
    R, t = pose_matrix(q[:6])
    x = hand.mesh.nodes + bone_displacements(hand, dict(zip(names, q[6:] + 0.02)))
    skin = np.unique(hand.skin_facets)
    pick = rng.choice(skin, 150, replace=False)
    cloud = x[pick] @ R.T + t + rng.normal(0, 0.3, (150, 3))
    markers = (hand.mesh.nodes[pick[:5]], cloud[:5])
    r, J = tracker.linearise(q, cloud, markers)
    assert J.shape == (len(r), 6 + len(names)) and np.isfinite(J).all()
    d = rng.normal(size=len(q)) * np.r_[np.full(3, 0.01), np.ones(3), np.full(len(names), 0.05)]
    rems = []
    for eps in (1e-2, 5e-3):
        r2, _ = tracker.linearise(q + eps * d, cloud, markers)
        rems.append(np.linalg.norm(r2 - r - eps * J @ d))
    assert rems[1] < 0.35 * rems[0]  # second order: a quarter, with room for the distances' kinks
    assert rems[1] < 0.05 * np.linalg.norm(eps * J @ d)


def test_strain_map_carried_between_hand_meshes(hand):
    """A linear field of the facet centres on a finer hand's skin, carried onto the coarse skin,
    differs from the field at the coarse centres by at most the fine facets' size times its slope."""
    fine = coarse_hand(15.0)
    g = np.random.default_rng(0).normal(size=3)
    field = lambda h: h.mesh.nodes[h.skin_facets[:, :3]].mean(1) @ g  # noqa: E731
    out = skin_strain_on(fine, field(fine), hand)
    assert np.isfinite(out).all()
    assert np.abs(out - field(hand)).max() <= 15.0 * np.linalg.norm(g)
    with pytest.raises(CorrespondenceError, match="one value per skin facet"):
        skin_strain_on(fine, field(fine)[:-1], hand)


def test_bad_input(hand, tracker):
    rng = np.random.default_rng(5)
    X = hand.mesh.nodes[np.unique(hand.skin_facets)]
    with pytest.raises(CorrespondenceError, match="needs a range cloud, markers or both"):
        tracker.fit_frame()
    with pytest.raises(CorrespondenceError, match="holds no"):
        tracker.fit_frame(np.zeros((0, 3)))
    with pytest.raises(CorrespondenceError, match="holds no"):
        tracker.fit_frame(np.full((4, 3), np.nan))
    with pytest.raises(CorrespondenceError, match=r"\(n, 3\)"):
        tracker.fit_frame(X[:, :2])
    far = X + rng.uniform(200, 400) * rng.choice([-1, 1], 3)  # drawn: a cloud in another frame
    with pytest.raises(CorrespondenceError, match="mm \\(median\\) from the hand"):
        tracker.fit_frame(far)
    with pytest.raises(CorrespondenceError, match="markers off the hand model"):
        tracker.fit_frame(markers=(X[:3] + [0.0, 0.0, 500.0], X[:3]))
    with pytest.raises(CorrespondenceError, match="no joint angle"):
        HandTracker(tracker.model, names=("wrist_flexion", "elbow"))
    with pytest.raises(CorrespondenceError, match="range frames but markers"):
        tracker.track([X, X], (X[:3], np.stack([X[:3]] * 3)))


def test_restart_from_other_starts_when_the_fit_ends_high(hand, tracker):
    """A frame started with one angle off by one restart offset (drawn: which angle of two, its sign,
    the angles, pose and noise) and no first trials (``iterations=0``) ends at a high cost: the
    restart from the start moved back by that offset wins and ends with that angle near the truth; with
    ``restart_cost=inf`` nothing restarts and the fit stays at its start."""
    rng = np.random.default_rng(7)
    names, off = tracker.names, 0.2
    truth = rng.uniform(-0.15, 0.15, len(names))
    pose = np.r_[rng.uniform(-0.03, 0.03, 3), rng.uniform(-2, 2, 3)]
    R, t = pose_matrix(pose)
    x = hand.mesh.nodes + bone_displacements(hand, dict(zip(names, truth)))  # rigid bones, not the FE model
    skin = np.unique(hand.skin_facets)
    cloud = x[skin] @ R.T + t + rng.normal(0, 0.2, (len(skin), 3))
    moved, sign = rng.choice(["wrist_flexion", "thumb_2"]), rng.choice([-1.0, 1.0])
    a0 = truth.copy()
    a0[names.index(moved)] += sign * off
    sol = tracker.model.solver.solve(tracker.model.params(dict(zip(names, a0))))  # the last frame's solve
    start = FrameFit(a0, pose, np.asarray(sol.u).reshape(-1, 3), np.nan, np.nan, 0, 0.0)
    cfg = replace(tracker.config, iterations=0, restart_cost=0.0, restart_angles=("wrist_flexion", "thumb_2"),
                  restart_offsets=(off, -off), restart_trials=1)
    fit = tracker.with_config(cfg).fit_frame(cloud, start=start)
    assert fit.restarted and fit.restart == 2 * ("wrist_flexion", "thumb_2").index(moved) + (sign > 0)
    k = names.index(moved)  # the rigid-bone data against the FE skin leave the coupled thumb angles a few degrees off
    assert abs(fit.angles[k] - truth[k]) < 0.25 * off, np.degrees(fit.angles - truth)
    stay = tracker.with_config(replace(cfg, restart_cost=np.inf)).fit_frame(cloud, start=start)
    assert not stay.restarted and np.allclose(stay.angles, a0) and stay.cost > fit.cost
    # a limit between the winner's cost and the first fit's: the search stops at the winner
    n = len(cloud[: tracker.config.max_points])
    first = tracker.with_config(replace(cfg, restart_cost=np.sqrt(fit.cost * stay.cost) / n)).fit_frame(cloud, start=start)
    assert first.restart == fit.restart and first.iterations == fit.restart + 1 < fit.iterations
    with pytest.raises(CorrespondenceError, match="restart_angles"):
        tracker.with_config(replace(cfg, restart_angles=("index_1",)))
    with pytest.raises(CorrespondenceError, match="compiled into"):
        tracker.with_config(replace(cfg, max_points=100))


def test_hand_mesh_refined_along_the_thumb():
    """``hand_mesh(..., fine=along(body, names, h, axis))``: every grid gap along the named phalanges'
    length is at most ``h`` (a drawn size), the grid elsewhere is the unrefined one's, the mesh is
    larger; bad rows and names are refused."""
    from jaxfem import MeshError
    from tests._hand_util import COARSE
    body = default_body(COARSE)
    h = float(np.random.default_rng(4).uniform(4.0, 8.0))
    rows = along(body, ("thumb_1", "thumb_2"), h, 0)  # the thumb lies along x
    plain, fine = hand_mesh(body, 30.0, 4.5), hand_mesh(body, 30.0, 4.5, rows)
    lo, hi = rows[0][1], rows[1][2]
    x = fine.mesh.nodes[:, 0]
    xs = np.unique(x[(x >= lo - 1e-9) & (x <= hi + 1e-9)].round(9))  # the refined rows
    assert np.diff(xs).max() <= h / 2 + 1e-9  # tet10: mid-edge nodes halve the gaps
    assert np.diff(xs).max() > h / 4  # no finer than asked (ceil rounding)
    keep = lambda m: np.unique(m.mesh.nodes[m.mesh.nodes[:, 0] < lo - 1e-9].round(9), axis=0)  # noqa: E731
    assert np.array_equal(keep(plain), keep(fine))
    assert fine.mesh.n_cells > plain.mesh.n_cells
    with pytest.raises(MeshError, match="no volume"):
        along(body, ("thumb_3",), h, 0)
    with pytest.raises(MeshError, match="axis 0-2"):
        hand_mesh(body, 30.0, 4.5, ((3, 0.0, 1.0, 5.0),))
    with pytest.raises(MeshError, match="axis 0-2"):
        hand_mesh(body, 30.0, 4.5, ((0, 0.0, 1.0, 0.0),))


def _frame_data(hand, tracker, seed):
    """A cloud of the rigid-bone hand (the skin nodes) at drawn angles and pose, with noise: ``(truth
    angles, pose, cloud)``."""
    rng = np.random.default_rng(seed)
    truth = rng.uniform(-0.15, 0.15, len(tracker.names))
    pose = np.r_[rng.uniform(-0.03, 0.03, 3), rng.uniform(-2, 2, 3)]
    R, t = pose_matrix(pose)
    x = hand.mesh.nodes + bone_displacements(hand, dict(zip(tracker.names, truth)))
    skin = np.unique(hand.skin_facets)
    return truth, pose, x[skin] @ R.T + t + rng.normal(0, 0.2, (len(skin), 3))


def _fit_at(tracker, angles, pose):
    """A :class:`FrameFit` at ``angles``, ``pose`` with the model's solve there (a last frame's fit)."""
    sol = tracker.model.solver.solve(tracker.model.params(dict(zip(tracker.names, angles))))
    return FrameFit(np.asarray(angles, float), np.asarray(pose, float), np.asarray(sol.u).reshape(-1, 3), np.nan,
                    np.nan, 0, 0.0)


def test_each_frame_starts_from_the_constant_velocity_prediction(hand, tracker):
    """Two earlier fits a drawn step apart along a drawn direction, the truth one more step on: with
    no trials (``iterations=0``) the fit ends at the prediction (within the step's rounding) at a lower
    cost than from the last fit, which ``predict=False`` keeps."""
    truth, pose, cloud = _frame_data(hand, tracker, 11)
    rng = np.random.default_rng(12)
    step = rng.normal(size=len(truth)) * 0.08
    before, start = _fit_at(tracker, truth - 2 * step, pose), _fit_at(tracker, truth - step, pose)
    cfg = replace(tracker.config, iterations=0, restart_cost=np.inf)
    fit = tracker.with_config(cfg).fit_frame(cloud, start=start, before=before)
    assert fit.predicted and np.allclose(fit.angles, truth, atol=1e-9)
    last = tracker.with_config(replace(cfg, predict=False)).fit_frame(cloud, start=start, before=before)
    assert not last.predicted and np.allclose(last.angles, start.angles) and last.cost > fit.cost


@functools.lru_cache(maxsize=1)
def _sequence(seed):
    return hand_range_sequence(seed=seed, frames=4, h=12.0)  # steps of up to ~12 degrees (at 25 the thumb was lost)


@functools.lru_cache(maxsize=2)
def _model(thumb_h):
    """The default tracking model (``thumb_h`` = 6: the paper-size hand with its thumb split along its
    length to 6 mm, 2,682 tet10), or the paper-size model as it is (``None``: 2,412 tet10)."""
    return tracking_model(thumb_h)


CLOUDS_ALONE_SHORT = pytest.mark.xfail(
    reason="known shortfall of the paper-size model: seed 1's thumb tip (flexed ~73 degrees towards the palm in all, "
           "seen from the back: ~58 points on its phalanx) ends 1.31 degrees off from the clouds alone per frame, 1.14 "
           "smoothed: the model's own floor (noise-free clouds leave 0.51-0.60), which the temporal prior does not "
           "average away; the default model (refined along the thumb) gives 0.83 smoothed", strict=True)


@pytest.mark.slow  # three finer data solves, each tracked three ways by the default model and smoothed, and two cases
# of the paper-size model (~50 min, 2 quiet shared cores)
@pytest.mark.parametrize("seed, kind, thumb_h", [
    (0, "clouds", 6.0), (0, "markers", 6.0), (0, "both", 6.0),
    (1, "clouds", 6.0), (1, "markers", 6.0), (1, "both", 6.0), pytest.param(1, "clouds", None, marks=CLOUDS_ALONE_SHORT),
    (2, "clouds", 6.0), (2, "markers", 6.0), (2, "both", 6.0),
    (2, "markers", None)])
def test_joint_angles_within_a_degree_from_range_clouds_markers_and_both(seed, kind, thumb_h):
    """The default tracking model (refined along the thumb, 2,682 tet10; ``thumb_h=None``: the
    paper-size model, 2,412) against sequences generated on a finer mesh (4,248) with noise, angles
    and pose drawn under each seed, tracked frame by frame and smoothed over the sequence
    (:func:`examples.hand.smooth`): every angle of every frame within 1 degree from the clouds and the
    markers together (the paper's set-up) and from the clouds alone; from the markers alone (13 at
    0.1 mm: noise-limited at 1 degree, a correct fit ends some angle beyond it in ~16 % of such
    sequences, benchmarks/_hand_marker_noise.py) the sequence's errors within the reported
    uncertainty (:func:`examples.hand.error_chi2` over every angle of every frame, p >= 0.01; seed 2's
    thumb tip, 1.22 degrees off, gives p = 0.40 in the benchmark's identical run). Seed 2's finger,
    lost in frame 1 from the rest frame's estimate, is found by the tracker's restarts; every later
    frame starts from the constant-velocity prediction. The paper-size model: seed 1 from the clouds
    stays a strict xfail (its floor at the thumb); seed 2 from the markers alone is judged the same
    way."""
    seq = _sequence(seed)
    tracker = HandTracker(_model(thumb_h), TrackConfig(seed=seed))
    assert all(len(c) > 1000 for c in seq.clouds)
    assert tracker.names == seq.names
    data = {"clouds": {"clouds": seq.clouds}, "markers": {"markers": (seq.marker_reference, seq.markers)}}
    data["both"] = data["clouds"] | data["markers"]
    smoothed = smooth(tracker, tracker.track(**data[kind]), **data[kind])
    err = angle_errors(smoothed.fits, seq.angles)
    if kind == "markers":  # noise-limited at 1 degree: judged by the reported covariance (benchmarks/_hand_tracking)
        assert error_chi2(smoothed.fits, seq.angles, smoothed.covariance)["p"] >= 0.01, err
    else:
        assert np.abs(err).max() < 1.0, err
    assert np.abs(smoothed.fits[-1].pose[3:] - seq.pose[3:]).max() < 1.0
    assert np.isfinite(smoothed.std).all() and (smoothed.std <= smoothed.frame_std).all()
