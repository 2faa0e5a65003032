"""The hand tracker's temporal prior (examples.hand.smooth): the whole-sequence Gauss-Newton step
against an independent least-squares solve, its covariance (each frame's and the whole
sequence's) against the spread of many noisy draws, the sequence's chi-square in that covariance
(examples.hand.error_chi2: calibrated, and it flags an error the frames share), its bias at a
sudden reversal (bounded by the Cauchy release, not by a Gaussian prior), and the smoother on a
tracked sequence of the coarse hand from noisy markers (drawn angles, pose, noise)."""

from types import SimpleNamespace

import numpy as np
import pytest

from examples.hand import HandModel
from refine.exceptions import CorrespondenceError, ExperimentError
from examples.hand import HandTracker, MotionModel, TrackConfig, angle_errors, error_chi2, smooth
from examples.hand.smooth import prior_cost, second_differences, sequence_covariance, smooth_quadratic
from examples.hand.range import STOP_REVERSE, hand_range_sequence, pose_matrix
from tests._hand_util import coarse_hand


def _problem(rng, K=7, n=3):
    """Per-frame information matrices ``H (K, n, n)`` (drawn, well conditioned) and their square roots."""
    A = rng.normal(size=(K, n, n))
    H = np.einsum("kij,klj->kil", A, A) + 2 * np.eye(n)
    return H, np.linalg.cholesky(H)


def _draw(rng, truth, H):
    """Per-frame estimates ``truth + N(0, H_k^-1)``."""
    L = np.linalg.cholesky(np.linalg.inv(H))
    return truth + np.einsum("kij,kj->ki", L, rng.normal(size=truth.shape))


def test_gaussian_smoother_is_the_weighted_least_squares_solution():
    rng = np.random.default_rng(0)
    H, C = _problem(rng)
    K, n = H.shape[:2]
    sigma = rng.uniform(0.1, 1.0, n)
    Q0 = rng.normal(size=(K, n))
    g = rng.normal(size=(K, n))
    Q, cov, _ = smooth_quadratic(Q0, g, H, sigma, np.inf)
    # the same objective as one stacked least-squares problem: C_k^T (q_k - (Q0_k - H_k^-1 g_k)); D q / sigma
    target = Q0 - np.linalg.solve(H, g[..., None])[..., 0]
    rows = [np.kron(np.eye(K)[k:k + 1], C[k].T) for k in range(K)]
    A = np.vstack(rows + [np.kron(second_differences(K), np.diag(1 / sigma))])
    b = np.r_[np.concatenate([C[k].T @ target[k] for k in range(K)]), np.zeros((K - 2) * n)]
    ref = np.linalg.lstsq(A, b, rcond=None)[0].reshape(K, n)
    assert np.allclose(Q, ref, atol=1e-10)
    assert np.allclose(cov, [np.linalg.inv(A.T @ A)[k * n:(k + 1) * n, k * n:(k + 1) * n] for k in range(K)], atol=1e-10)
    full = sequence_covariance(H, sigma, np.ones((K - 2, n)))  # the whole inverse, the frames' blocks and between them
    assert full.shape == (K, n, K, n) and np.allclose(full.reshape(K * n, K * n), np.linalg.inv(A.T @ A), atol=1e-10)
    assert prior_cost(ref, sigma, np.inf) == pytest.approx(np.sum((second_differences(K) @ ref / sigma) ** 2))


def test_smoothed_covariance_matches_the_spread_and_beats_each_frame():
    """Motions drawn from the prior (velocity changes N(0, sigma^2) per frame from a drawn start)
    seen per frame with noise N(0, H^-1): over 400 draws the smoothed errors' spread matches the
    reported standard deviations (within 20 % each, 5 % on average) and is below each frame's own;
    on a constant-velocity motion the reported deviations are conservative (the spread is smaller)."""
    rng = np.random.default_rng(1)
    H, _ = _problem(rng)
    K, n = H.shape[:2]
    sigma, errs, steady = np.full(n, 0.3), [], []
    line = rng.normal(size=n) + np.arange(K)[:, None] * rng.normal(size=n)
    for _ in range(400):
        truth = line + np.cumsum(np.cumsum(np.r_[np.zeros((2, n)), rng.normal(0, 1, (K - 2, n)) * sigma], 0), 0)
        Q, cov, w = smooth_quadratic(_draw(rng, truth, H), np.zeros((K, n)), H, sigma, np.inf)
        errs.append(Q - truth)
        steady.append(smooth_quadratic(_draw(rng, line, H), np.zeros((K, n)), H, sigma, np.inf)[0] - line)
    std = np.sqrt(np.stack([np.diag(c) for c in cov]))
    spread = np.std(errs, axis=0)
    assert np.abs(spread / std - 1).max() < 0.2 and np.abs(np.mean(spread / std) - 1) < 0.05
    assert (np.std(steady, axis=0) < 1.1 * std).all()
    frame = np.sqrt(np.stack([np.diag(np.linalg.inv(h)) for h in H]))
    assert (std < frame).all() and np.mean(std / frame) < 0.8


def _fits(Q):
    return [SimpleNamespace(angles=q) for q in Q]


def test_sequence_chi_square_is_calibrated_and_flags_an_error_the_frames_share():
    """Motions drawn from the prior, seen per frame with noise N(0, H^-1), smoothed: the sequence's
    errors in the whole covariance (error_chi2) fall below p = 0.05 in about 5 % of 300 draws and
    below 0.01 in about 1 %; the same with an offset of 2.5-3 of its smoothed deviations added to
    every frame of one drawn angle (as a reference position's error would be) falls below 0.01 in
    nearly every draw. A covariance of the wrong shape is refused."""
    rng = np.random.default_rng(5)
    H, _ = _problem(rng)
    K, n = H.shape[:2]
    sigma = np.full(n, 0.3)
    line = rng.normal(size=n) + np.arange(K)[:, None] * rng.normal(size=n)
    C = sequence_covariance(H, sigma, np.ones((K - 2, n)))
    std = np.sqrt(np.einsum("kiki->ki", C))
    j = int(rng.integers(n))
    p, p_offset = [], []
    for _ in range(300):
        truth = line + np.cumsum(np.cumsum(np.r_[np.zeros((2, n)), rng.normal(0, 1, (K - 2, n)) * sigma], 0), 0)
        Q = smooth_quadratic(_draw(rng, truth, H), np.zeros((K, n)), H, sigma, np.inf)[0]
        p.append(error_chi2(_fits(Q), truth, C)["p"])
        offset = np.eye(n)[j] * rng.uniform(2.5, 3.0) * std[:, j].max()
        Q = smooth_quadratic(_draw(rng, truth + offset, H), np.zeros((K, n)), H, sigma, np.inf)[0]
        p_offset.append(error_chi2(_fits(Q), truth, C)["p"])
    p, p_offset = np.array(p), np.array(p_offset)
    assert 0.02 < np.mean(p < 0.05) < 0.10 and np.mean(p < 0.01) < 0.04
    assert np.mean(p_offset < 0.01) > 0.85
    assert error_chi2(_fits(Q), truth, C)["dof"] == K * n
    with pytest.raises(CorrespondenceError, match="covariance of shape"):
        error_chi2(_fits(Q), truth, C[:-1])


def test_cauchy_release_bounds_the_bias_at_a_reversal():
    """A sudden reversal (a drawn velocity flipped at a drawn frame, 20 sigmas of velocity change):
    the Gaussian prior drags the turning frame by several of its noise deviations, the Cauchy
    release (2 sigmas) by under half of one; where the motion is smooth both shrink the errors."""
    rng = np.random.default_rng(2)
    H, _ = _problem(rng, K=8)
    K, n = H.shape[:2]
    sigma = np.full(n, 0.3)
    turn = int(rng.integers(2, K - 2))
    v = rng.choice([-1.0, 1.0], n) * 10 * sigma  # a velocity change of 20 sigma at the turn
    truth = np.array([v * min(k, 2 * turn - k) for k in range(K)])
    frame = np.sqrt(np.stack([np.diag(np.linalg.inv(h)) for h in H]))
    bias = {}
    for release in (np.inf, 2.0):
        errs = [smooth_quadratic(_draw(rng, truth, H), np.zeros((K, n)), H, sigma, release)[0] - truth
                for _ in range(200)]
        bias[release] = np.abs(np.mean(errs, axis=0)) / frame
    assert bias[np.inf][turn].max() > 2.0
    assert bias[2.0].max() < 0.5
    _, _, w = smooth_quadratic(truth, np.zeros((K, n)), H, sigma, 2.0)
    assert (w[turn - 1] < 0.05).all() and np.delete(w, turn - 1, axis=0).min() > 0.99  # let go at the turn only


def test_a_generated_motion_profile_of_the_wrong_length_is_refused():
    with pytest.raises(ExperimentError, match="one finite share per frame"):
        hand_range_sequence(frames=3, profile=STOP_REVERSE)
    with pytest.raises(ExperimentError, match="one finite share per frame"):
        hand_range_sequence(frames=4, profile=(0.0, 0.25, np.nan, 0.5, 0.25))


@pytest.fixture(scope="module")
def hand():
    return coarse_hand()


@pytest.mark.slow  # 65 s at load 9-10 on the shared 2 cores (compiling the coarse tracker, 4 frames tracked, smoothed)
def test_smoother_on_a_tracked_sequence_from_noisy_markers(hand):
    """Markers on the coarse hand's skin (drawn: 12 nodes, angles on a constant-velocity path of 4
    frames, pose, noise 0.4 mm; the model's own solve at the true angles, so that the errors are the noise's and
    the reported deviations can be checked): the smoothed angles' errors are below the per-frame
    fits' (RMS), each smoothed deviation below the frame's own, every error within 3 of them, no
    frame released, the objective below the fits'; bad input is refused."""
    rng = np.random.default_rng(8)
    tracker = HandTracker(HandModel(hand), TrackConfig(max_points=200, marker_noise=0.4, restart_cost=np.inf,
                                                       iterations=4))
    names, K, model = tracker.names, 4, tracker.model
    truth = np.linspace(0, 1, K)[:, None] * rng.uniform(-0.25, 0.25, len(names))
    pose = np.r_[rng.uniform(-0.03, 0.03, 3), rng.uniform(-2, 2, 3)]
    R, t = pose_matrix(pose)
    at = rng.choice(np.unique(hand.skin_facets), 12, replace=False)
    ref = hand.mesh.nodes[at]
    pos = np.stack([(ref + np.asarray(model.solver.solve(model.params(dict(zip(names, a)))).u)[at]) @ R.T + t
                    for a in truth])
    markers = (ref, pos + rng.normal(0, 0.4, pos.shape))
    fits = tracker.track(markers=markers)
    motion = MotionModel(iterations=1)
    seq = smooth(tracker, fits, markers=markers, motion=motion)
    e0, e1 = angle_errors(fits, truth), angle_errors(seq.fits, truth)
    assert np.sqrt(np.mean(e1 ** 2)) < np.sqrt(np.mean(e0 ** 2)), (e0, e1)
    assert (seq.std < seq.frame_std).all() and not seq.released.any()
    assert (np.abs(e1) < 3 * np.degrees(seq.std)).all(), (e1, np.degrees(seq.std))
    assert seq.covariance.shape == (K, len(names), K, len(names))  # its diagonal blocks are the reported deviations
    assert np.allclose(np.sqrt(np.einsum("kiki->ki", seq.covariance)), seq.std)
    assert error_chi2(seq.fits, truth, seq.covariance)["p"] > 0.001
    Q = np.array([np.r_[f.pose, f.angles] for f in fits])
    assert seq.objective < 0.5 * sum(f.cost for f in fits) + 0.5 * prior_cost(Q, motion.sigma(len(names)), motion.release)
    with pytest.raises(CorrespondenceError, match="needs the tracked data"):
        smooth(tracker, fits)
    with pytest.raises(CorrespondenceError, match="3 marker frames for 4 fits"):
        smooth(tracker, fits, markers=(ref, pos[:3]))
