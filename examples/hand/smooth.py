"""The temporal prior of hand tracking: a sequence's per-frame fits smoothed together.

:meth:`examples.hand.HandTracker.track` fits each frame alone (apart from its start). A sequence
carries more: the joints move smoothly in time. :func:`smooth` minimises, over the pose and the
joint angles of every frame ``Q (n_frames, 6 + n_angles)`` at once,

    1/2 sum_k cost_k(q_k)  +  1/2 sum_{k=1}^{n-2} sum_j rho(z_kj),   z_k = (q_{k-1} - 2 q_k + q_{k+1}) / sigma,

where ``cost_k`` is the tracker's own robust cost of frame ``k`` (its residuals in noise units) and
``rho(z) = c^2 log(1 + z^2 / c^2)`` a Cauchy penalty on each second difference (the change of
velocity from one frame to the next) in units of the :class:`MotionModel`'s ``sigma``: a nearly
constant-velocity motion. The Cauchy penalty lets go of a velocity change far beyond ``sigma``
(a start, a stop, a reversal): there the prior's pull on the estimate is bounded (at most
``c / 2`` noise units of force), so it does not drag a sudden change. Gauss-Newton over the whole
sequence (the frames' Jacobians through the solve, one evaluation per frame and iteration; the
prior's weights refreshed to convergence within each linearisation), started at the per-frame fits.

Each angle's uncertainty is the Laplace (Gauss-Newton) standard deviation: the square root of the
diagonal of the inverse of the whole sequence's Gauss-Newton matrix at the end (the data term's
``J^T W J`` per frame plus the prior's), under the tracker's stated noise; beside it, that of each
frame alone (``J^T W J`` of the frame). Neither holds the model's own discretisation error.
The smoothed errors of neighbouring frames are correlated (the prior ties them): ``covariance``
holds the whole sequence's angle covariance, so an error shared by several frames is judged
against what the frames share (:func:`examples.hand.compare.error_chi2`), not frame by frame.

The limit: the prior's pull on a sudden change is largest for a change near its release (a few
sigmas) and grows with the square of a frame's own standard deviation: measured exactly, a stop
is biased by at most 0.02 / 0.14 / 0.43 / 1.14 degrees where a frame knows the angle to 0.1 /
0.3 / 0.6 / 0.9 degrees (benchmarks/_hand_tracking.prior_bias, default :class:`MotionModel`).

Units: radians, mm; ``sigma`` per frame squared (frames are equally spaced in time).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from refine.exceptions import CorrespondenceError
from examples.hand.starts import fit_vector


@dataclass(frozen=True)
class MotionModel:
    """The stated motion of the hand between frames (data), the smoother's prior.

    Each joint angle moves at a nearly constant velocity whose change from one frame to the next
    (the second difference) is about ``angle`` (radians per frame squared; the default 1 degree per
    frame squared is 900 degrees/s^2 at a 30 Hz scanner: a hand moved steadily through its range, as
    in the paper's range-of-motion experiment); the global pose (a held forearm in the scanner's
    frame) changes its velocity by about ``rotation`` (radians per frame squared) and
    ``translation`` (mm per frame squared). A velocity change beyond about ``release`` x its sigma
    is an event the prior lets go of (Cauchy scale, in sigmas; ``inf``: a Gaussian prior that
    drags every event).

    Attributes:
        angle, rotation, translation: the sigmas above.
        release: the Cauchy scale of the penalty (in sigmas).
        iterations: most Gauss-Newton iterations over the sequence (each one evaluation per frame,
            plus one per halving of a step that raised the objective).
        step_tol: stop when no angle moves more than this (radians).
    """

    angle: float = float(np.radians(1.0))
    rotation: float = float(np.radians(0.2))
    translation: float = 0.2
    release: float = 2.0
    iterations: int = 4
    step_tol: float = 1e-5

    def sigma(self, n_angles: int) -> np.ndarray:
        """The sigma of each unknown ``(6 + n_angles,)``: pose rotation, translation, then the angles."""
        return np.r_[np.full(3, self.rotation), np.full(3, self.translation), np.full(n_angles, self.angle)]


@dataclass(frozen=True)
class SmoothedSequence:
    """The smoothed sequence.

    Attributes:
        fits: the smoothed :class:`~examples.hand.FrameFit` per frame (``u``, ``rms``, ``cost`` at the
            smoothed angles; ``iterations`` and ``seconds`` those of the frame's own fit).
        frames: the per-frame fits smoothed.
        std: each angle's standard deviation after smoothing ``(n_frames, n_angles)`` radians;
            pose_std ``(n_frames, 6)`` (radians, mm).
        frame_std: each angle's standard deviation from its frame alone ``(n_frames, n_angles)``.
        covariance: the angles' covariance over the whole sequence ``(n_frames, n_angles, n_frames,
            n_angles)`` radians^2 (its diagonal blocks give ``std``; the off-diagonal ones the
            correlation the prior puts between frames).
        released: per frame, whether the prior let go of a joint's velocity change there (its
            Cauchy weight below 1/2: a start, stop or reversal; ``(n_frames,)``, False at the ends).
        objective: the smoothed objective (noise units squared; prior included); iterations:
            Gauss-Newton iterations taken; seconds: the smoother's time.
    """

    fits: list
    frames: list
    std: np.ndarray
    pose_std: np.ndarray
    frame_std: np.ndarray
    released: np.ndarray
    objective: float
    iterations: int
    seconds: float
    covariance: np.ndarray | None = None


def second_differences(n_frames: int) -> np.ndarray:
    """``D (n_frames - 2, n_frames)``: row ``k`` takes ``q_k - 2 q_{k+1} + q_{k+2}`` (none under 3 frames)."""
    D = np.zeros((max(n_frames - 2, 0), n_frames))
    for k in range(len(D)):
        D[k, k:k + 3] = (1.0, -2.0, 1.0)
    return D


def prior_cost(Q: np.ndarray, sigma: np.ndarray, release: float) -> float:
    """``sum rho(z)`` of the second differences of ``Q (n_frames, n)`` in units of ``sigma (n,)``."""
    z = second_differences(len(Q)) @ Q / sigma
    return float(np.sum(z * z if np.isinf(release) else release ** 2 * np.log1p((z / release) ** 2)))


def smooth_quadratic(Q0, g, H, sigma, release: float, inner: int = 100, tol: float = 1e-12):
    """The smoothed ``Q (n_frames, n)`` of a quadratic data term about ``Q0 (n_frames, n)``
    (gradients ``g (n_frames, n)``, Gauss-Newton matrices ``H (n_frames, n, n)``: the data term
    ``sum_k g_k.d_k + 1/2 d_k H_k d_k``, ``d = Q - Q0``) and the prior of the module docstring
    (``sigma (n,)``, Cauchy scale ``release``), by iteratively reweighted least squares on the
    prior's weights. Returns ``(Q, cov (n_frames, n, n), weights (n_frames - 2, n))``: ``cov`` the
    diagonal blocks of the inverse Gauss-Newton matrix at the end (the whole inverse:
    :func:`sequence_covariance` of ``H``, ``sigma`` and these ``weights``), ``weights`` the prior's.

    Raises:
        CorrespondenceError: the system is singular (an unknown no frame and no prior determines).
    """
    Q0, g, H = (np.asarray(v, float) for v in (Q0, g, H))
    K, n = Q0.shape
    D, s2, Hb = _system(H, sigma)
    rhs = np.einsum("kij,kj->ki", H, Q0).reshape(-1) - g.reshape(-1)
    w = np.ones(len(s2))
    for _ in range(inner):
        A = Hb + D.T @ ((w * s2)[:, None] * D)
        try:
            Q = np.linalg.solve(A, rhs)
        except np.linalg.LinAlgError:
            raise CorrespondenceError("the smoothed sequence is undetermined (an unknown no frame's data and no "
                                      "prior fixes); fit fewer angles or give more data") from None
        if np.isinf(release):
            break
        w_new = 1.0 / (1.0 + (D @ Q) ** 2 * s2 / release ** 2)
        done = np.abs(w_new - w).max(initial=0.0) < tol
        w = w_new
        if done:
            break
    w = w.reshape(max(K - 2, 0), n)
    cov = sequence_covariance(H, sigma, w).reshape(K * n, K * n)
    blocks = np.stack([cov[k * n:(k + 1) * n, k * n:(k + 1) * n] for k in range(K)])
    return Q.reshape(K, n), blocks, w


def _system(H, sigma):
    """The pieces of the whole sequence's Gauss-Newton matrix: ``D`` (second differences of every
    unknown, ``((K - 2) n, K n)``), ``1 / sigma^2`` per row of ``D``, and the block diagonal of the
    frames' ``H (K, n, n)``."""
    K, n = H.shape[:2]
    D = np.kron(second_differences(K), np.eye(n))
    s2 = np.tile(1.0 / np.asarray(sigma, float) ** 2, max(K - 2, 0))
    Hb = np.zeros((K * n, K * n))
    for k in range(K):
        Hb[k * n:(k + 1) * n, k * n:(k + 1) * n] = H[k]
    return D, s2, Hb


def sequence_covariance(H, sigma, weights) -> np.ndarray:
    """The whole sequence's covariance ``(K, n, K, n)``: the inverse of its Gauss-Newton matrix
    (the frames' ``H (K, n, n)`` plus the prior's ``D^T diag(weights / sigma^2) D``, ``weights
    (K - 2, n)`` the prior's Cauchy weights, ``sigma (n,)``), in the unknowns' units squared."""
    H = np.asarray(H, float)
    K, n = H.shape[:2]
    D, s2, Hb = _system(H, sigma)
    A = Hb + D.T @ ((np.asarray(weights, float).reshape(-1) * s2)[:, None] * D)
    return np.linalg.inv(A).reshape(K, n, K, n)


def _normal(state, free):
    """The frame's gradient ``g (n,)`` and Gauss-Newton matrix ``H (n, n)`` of ``cost / 2`` (the
    tracker's robust weights), fixed unknowns (not ``free``) held by a unit diagonal."""
    JW = state["J"] * state["w"][:, None]
    H, g = JW.T @ state["J"], JW.T @ state["r"]
    H[~free], H[:, ~free], g[~free] = 0.0, 0.0, 0.0
    H[~free, ~free] = 1.0
    return g, H


def smooth(tracker, fits, clouds=None, markers=None, motion: MotionModel = MotionModel()) -> SmoothedSequence:
    """Smooth the per-frame ``fits`` (:meth:`examples.hand.HandTracker.track` of the same data:
    ``clouds`` a sequence of ``(n_k, 3)`` or None, ``markers`` ``(reference (m, 3), positions
    (n_frames, m, 3))`` or None) under ``motion`` (module docstring).

    Raises:
        CorrespondenceError: no data, a data length other than the fits', a singular sequence.
    """
    t0 = time.perf_counter()
    if clouds is None and markers is None:
        raise CorrespondenceError("smoothing needs the tracked data: range clouds, markers or both")
    K, n_a = len(fits), len(tracker.names)
    for name, seq in (("range clouds", clouds), ("marker frames", None if markers is None else markers[1])):
        if seq is not None and len(seq) != K:
            raise CorrespondenceError(f"{len(seq)} {name} for {K} fits: give the data the fits were tracked from")
    data = [(None if clouds is None else clouds[k], None if markers is None else (markers[0], markers[1][k]))
            for k in range(K)]
    free = np.r_[np.full(6, bool(tracker.config.pose)), np.ones(n_a, bool)]
    sigma = np.where(free, motion.sigma(n_a), np.inf)  # a fixed unknown has no prior

    def at(Q, starts):
        states = [tracker.evaluate(Q[k], *data[k], start=starts[k]) for k in range(K)]
        value = 0.5 * sum(s["cost"] for s in states) + 0.5 * prior_cost(Q, sigma, motion.release)
        return states, value

    Q = np.array([fit_vector(f, n_a) for f in fits])
    states, value = at(Q, fits)
    frame_cov = [np.linalg.pinv(_normal(s, free)[1]) for s in states]
    current, it = list(fits), 0
    for it in range(1, motion.iterations + 1):
        g, H = zip(*(_normal(s, free) for s in states))
        Qn, _, _ = smooth_quadratic(Q, g, H, sigma, motion.release)
        step = Qn - Q
        for _ in range(4):  # halve a step that raises the objective
            trial = Q + step
            try:
                new_states, new_value = at(trial, current)
            except CorrespondenceError:  # a solve failed at the trial: a shorter step
                new_value = np.inf
            if new_value <= value:
                break
            step = step / 2
        else:
            break
        Q, states, value = trial, new_states, new_value
        current = [_fit(fits[k], Q[k], states[k], tracker) for k in range(K)]
        if np.abs(step[:, 6:]).max() < motion.step_tol:
            break
    g, H = zip(*(_normal(s, free) for s in states))
    _, cov, w = smooth_quadratic(Q, np.zeros_like(Q), H, sigma, motion.release)
    full = sequence_covariance(np.stack(H), sigma, w)[:, 6:, :, 6:]
    released = np.zeros(K, bool)
    released[1:K - 1] = (w[:, 6:] < 0.5).any(axis=1) if K > 2 else False
    std = np.sqrt(np.stack([np.diag(c) for c in cov]))
    return SmoothedSequence([_fit(fits[k], Q[k], states[k], tracker) for k in range(K)], list(fits), std[:, 6:],
                            np.where(free[:6], std[:, :6], 0.0), np.sqrt(np.stack([np.diag(c) for c in frame_cov]))[:, 6:],
                            released, float(value), it, time.perf_counter() - t0, full)


def _fit(fit, q, state, tracker):
    """``fit`` moved to ``q (6 + n_angles,)`` with the evaluation ``state`` there."""
    return replace(fit, angles=q[6:].copy(), pose=q[:6].copy(), u=np.asarray(state["x"]) - tracker.model.hand.mesh.nodes,
                   rms=state["rms"], marker_rms=state["marker_rms"], cost=float(state["cost"]))
