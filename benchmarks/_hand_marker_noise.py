"""benchmarks/hand.py's marker-noise section (issue 25, item 5): how far the markers alone can
track the hand, i.e. whether a joint angle off by more than 1 degree from the 13 markers is the
tracker's fault or the markers' noise.

For a generated sequence (``examples.hand.range``, one seed) the markers' noise-free
positions (the fine solve's skin nodes, posed) and the tracker's exact Jacobian at the true angles
and pose of every frame give the linearised fit: per frame ``dq = -(J^T J)^-1 J^T r``, over the
sequence the smoother's quadratic (:func:`examples.hand.smooth.smooth_quadratic`, the default
:class:`~examples.hand.MotionModel`). ``r`` is the noise-free residual (the model's own error at
the markers: the floor) minus a fresh noise draw (``MARKER_NOISE`` per coordinate) in every frame,
``draws`` draws under a seed: the spread of the smoothed errors against the reported deviations
(the sequence covariance's diagonal), the chance that some angle of some frame ends beyond 1 degree,
the quantiles of the largest error, and the chi-square of the draws in the reported covariance.
The committed sequence's own noise is fitted the same way (``committed``), to compare with the
nonlinear tracking of the same data (the tracking section).

Units: degrees (radians in the fits).
"""

from __future__ import annotations

import time

import numpy as np
from scipy.stats import chi2

from examples.hand import HandTracker, MotionModel, TrackConfig
from examples.hand.smooth import sequence_covariance, smooth_quadratic
from examples.hand.range import hand_range_sequence, pose_matrix

DRAWS = 2000


def clean_markers(seq) -> np.ndarray:
    """The markers' noise-free positions ``(n_frames, m, 3)`` (mm, scanner frame) of ``seq``."""
    X = seq.hand.mesh.nodes
    at = np.array([np.flatnonzero(np.all(X == r, axis=1))[0] for r in seq.marker_reference])
    R, t = pose_matrix(seq.pose)
    return np.stack([(X[at] + u[at]) @ R.T + t for u in seq.u])


def linearised(tracker, seq, clean):
    """Per frame, the markers' residual rows at the truth: ``(J (K, 3m, n), r_clean (K, 3m), q (K, n))``."""
    K = len(seq.angles)
    Q = np.c_[np.tile(seq.pose, (K, 1)), seq.angles]
    rows = slice(tracker.config.max_points, None)
    states = [tracker.evaluate(Q[k], markers=(seq.marker_reference, clean[k])) for k in range(K)]
    return np.stack([s["J"][rows] for s in states]), np.stack([s["r"][rows] for s in states]), Q


def _fit(J, rc, Q, eps, motion):
    """Per-frame and smoothed angle errors (degrees, ``(K, n_angles)`` each) for noise ``eps (K, 3m)``
    (noise units)."""
    H = np.einsum("kri,krj->kij", J, J)
    g = np.einsum("kri,kr->ki", J, rc - eps)
    per = -np.linalg.solve(H, g[..., None])[..., 0]
    smoothed = smooth_quadratic(Q, g, H, motion.sigma(Q.shape[1] - 6), motion.release)[0] - Q
    return np.degrees(per[:, 6:]), np.degrees(smoothed[:, 6:])


def noise_limit(model, seed: int, draws: int = DRAWS, motion: MotionModel = MotionModel(), **generate) -> dict:
    """The markers-alone noise limit of ``model`` on the sequence of ``seed`` (module docstring)."""
    t0 = time.perf_counter()
    seq = hand_range_sequence(seed=seed, **generate)
    clean = clean_markers(seq)
    tracker = HandTracker(model, TrackConfig(noise=seq.noise, marker_noise=seq.marker_noise, seed=seed))
    J, rc, Q = linearised(tracker, seq, clean)
    K, n_a = seq.angles.shape
    H = np.einsum("kri,krj->kij", J, J)
    C = sequence_covariance(H, motion.sigma(n_a), np.ones((K - 2, 6 + n_a)))[:, 6:, :, 6:]
    Cd = np.degrees(np.degrees(C)).reshape(K * n_a, K * n_a)
    std = np.sqrt(np.diag(Cd)).reshape(K, n_a)
    floor = _fit(J, rc, Q, np.zeros_like(rc), motion)
    committed = _fit(J, rc, Q, ((seq.markers - clean) / seq.marker_noise).reshape(K, -1), motion)
    rng = np.random.default_rng(1000 + seed)
    per, sm = map(np.array, zip(*(_fit(J, rc, Q, rng.normal(size=rc.shape), motion) for _ in range(draws))))
    largest = np.abs(sm).max(axis=(1, 2))
    d2 = np.einsum("di,ij,dj->d", sm.reshape(draws, -1), np.linalg.inv(Cd), sm.reshape(draws, -1))
    e = committed[1].reshape(-1)
    return {"seed": seed, "draws": draws, "angles": list(seq.names), "marker_noise_mm": seq.marker_noise,
            "floor_smoothed_deg": floor[1].round(4).tolist(), "floor_per_frame_deg": floor[0].round(4).tolist(),
            "committed_smoothed_deg": committed[1].round(4).tolist(),
            "committed_per_frame_deg": committed[0].round(4).tolist(),
            "committed_chi2": float(e @ np.linalg.solve(Cd, e)), "chi2_dof": K * n_a,
            "reported_std_deg": std.round(4).tolist(), "spread_deg": sm.std(axis=0).round(4).tolist(),
            "per_frame_spread_deg": per.std(axis=0).round(4).tolist(),
            "spread_over_reported": [float((sm.std(axis=0) / std).min()), float((sm.std(axis=0) / std).max())],
            "p_some_error_over_1_deg": float(np.mean(largest > 1.0)),
            "p_some_error_over_1_deg_per_frame": float(np.mean(np.abs(per).max(axis=(1, 2)) > 1.0)),
            "largest_error_quantiles_deg": dict(zip(("50", "90", "95"), np.quantile(largest, [0.5, 0.9, 0.95]).tolist())),
            "p_every_error_within_2_std": float(np.mean((np.abs(sm) <= 2 * std).all(axis=(1, 2)))),
            "p_chi2_p_below_0.01": float(np.mean(chi2.sf(d2, K * n_a) < 0.01)),
            "seconds": time.perf_counter() - t0}


def targets(res: dict) -> dict:
    """hand.json's informational rows of the sections ``marker_noise`` (the paper-size model) and
    ``marker_noise_thumb`` (the default model, suffixed ``_thumb_model``): no pass, the limit that
    the markers-alone rows are judged against."""
    out = {}
    for key, suffix in (("marker_noise", ""), ("marker_noise_thumb", "_thumb_model")):
        runs = res.get(key, {}).get("runs", [])
        if runs:
            out[f"markers_alone_noise_limit{suffix}"] = {
                "informational": "the markers alone (13, 0.1 mm), linearised at the truth, fresh noise in every frame: "
                                 "the chance that some angle of some frame of the smoothed sequence ends beyond 1 degree "
                                 "(a correct tracker's), the largest error's quantiles, and the reported deviations "
                                 "against the draws' spread",
                **{f"{k}_by_seed": {r["seed"]: r[k] for r in runs} for k in (
                    "p_some_error_over_1_deg", "p_some_error_over_1_deg_per_frame", "largest_error_quantiles_deg",
                    "spread_over_reported", "p_every_error_within_2_std", "p_chi2_p_below_0.01", "committed_chi2")}}
    return out
