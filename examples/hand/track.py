"""Tracking the hand: the joint angles (and a global pose) of a coarse articulated FE hand fitted
to each frame's data, (a) an unlabelled range cloud and/or (b) a handful of marked points.

The model is :class:`examples.hand.HandModel`: the bones drive the soft tissue as kinematic
Dirichlet data, and :meth:`~examples.hand.HandModel.drive` makes that data a JAX function of the
joint angles, so the deformed skin ``x(a)`` is differentiable in the angles through the solve
(the implicit function theorem: one Newton solve and one tangent solve per angle, ``jax.jacfwd``).
The scanner sees the model at a global pose ``y = R(w) x + t`` (rotation vector ``w``, radians;
translation ``t``, mm); the held forearm makes the pose and the angles separable.

Residuals (in noise units, robust: Cauchy weights refreshed every iteration):
- (a) each cloud point's distance to the model's boundary: flat triangles of the deformed
  quadratic faces (:func:`refine.correspond.geometry.boundary_facets`), the point against its
  ``candidates`` nearest triangles (by centroid, chosen on the host at the current estimate and
  fixed within one evaluation), :func:`~refine.correspond.geometry.triangle_distances` and a
  :func:`~refine.correspond.geometry.softmin` over them;
- (b) each marker's model position (the point of the coarse mesh at its reference position,
  :func:`jaxfem.locate`) minus its measured position.
They are minimised per frame by Levenberg-Marquardt over ``(w, t, a)`` from the constant-velocity
prediction of the last two fits (the first two frames: from the last fit, the first from the rest
pose), each trial a warm-started solve; a fit that ends at a high cost tries other starts
(:mod:`examples.hand.starts`).

Units: mm, radians.
"""

from __future__ import annotations

import copy
import time

import jax
import jax.numpy as jnp
import numpy as np
from scipy.spatial import cKDTree

import jaxfem as jf
from examples.hand.model import HandModel

from refine.correspond.geometry import boundary_facets, softmin, triangle_distances
from refine.correspond.model import rotation
from refine.exceptions import CorrespondenceError
from examples.hand.records import FrameFit, TrackConfig
from examples.hand.starts import fit_vector, predicted, restart_starts

__all__ = ["HandTracker", "TrackConfig", "FrameFit"]


def _pose_apply(pose, x):
    """``x (n, 3)`` moved by the pose ``(6,)``: rotation vector (radians), then translation (mm)."""
    return x @ rotation(pose[:3]).T + pose[3:]


class HandTracker:
    """Fits joint angles (and a global pose) of ``model`` to range clouds and/or markers.

    Args:
        model: the coarse :class:`examples.hand.HandModel` (compiled once; a scar passed as
            ``scar`` stiffens it).
        config: :class:`TrackConfig`.
        names: the angles fitted (default: every joint's); the others stay 0.
    """

    def __init__(self, model: HandModel, config: TrackConfig = TrackConfig(), scar=None, names=None):
        self.model, self.config = model, config
        self.names = tuple(names or model.hand.body.angle_names)
        unknown = set(self.names) - set(model.hand.body.angle_names)
        if unknown:
            raise CorrespondenceError(f"the hand has no joint angle(s) {sorted(unknown)}; its angles are "
                                      f"{model.hand.body.angle_names}")
        self._check_restarts(config)
        self.tri = boundary_facets(model.hand.mesh)
        self._theta0 = theta0 = model.params({}, scar)
        X = jnp.asarray(model.hand.mesh.nodes)

        def nodes(a, start):
            theta = {**theta0, "u_D": model.drive(dict(zip(self.names, a)))}
            x = X + model.solver.displacement(theta, start)
            return x, (x, theta["u_D"])

        self._nodes = jax.jit(jax.jacfwd(nodes, has_aux=True))  # (dx/da (n, 3, n_a), (x, u_D))
        self._linear = jax.jit(self._linearised)
        self._probes = {}

    def _check_restarts(self, config: TrackConfig) -> None:
        """Raises :class:`CorrespondenceError` where ``config.restart_angles`` names an angle the
        tracker does not fit."""
        unknown = set(config.restart_angles or ()) - set(self.names)
        if unknown:
            raise CorrespondenceError(f"restart_angles {sorted(unknown)} are not fitted angles; choose among {self.names}")

    #: the settings compiled into the residuals (a tracker with other values compiles anew)
    COMPILED = ("noise", "marker_noise", "max_points")

    def with_config(self, config: TrackConfig) -> "HandTracker":
        """This tracker (its compiled solve and residuals shared) with other settings of the
        fit: iterations, trust region, robust scale, restarts; ``COMPILED`` ones must stay."""
        changed = [k for k in self.COMPILED if getattr(config, k) != getattr(self.config, k)]
        if changed:
            raise CorrespondenceError(f"{changed} are compiled into this tracker's residuals: build a new "
                                      "HandTracker for other values")
        self._check_restarts(config)
        other = copy.copy(self)
        other.config = config
        return other

    # ------------------------------------------------------------------ residuals
    def _residuals(self, pose, x, P, cand, wP, probe_nodes, probe_w, M, wM):
        c = self.config
        y = _pose_apply(pose, x)
        tri = jnp.asarray(self.tri)
        A, B, C = y[tri[:, 0]], y[tri[:, 1]], y[tri[:, 2]]
        d = jax.vmap(lambda p, k: triangle_distances(p[None], A[k], B[k], C[k])[0])(P, cand)
        r_cloud = wP * softmin(d, 0.05 * c.noise) / c.noise
        at = jnp.einsum("mk,mkd->md", probe_w, y[probe_nodes])
        r_mark = (wM[:, None] * (at - M) / c.marker_noise).reshape(-1)
        return jnp.concatenate([r_cloud, r_mark])

    def _linearised(self, pose, x, dx, data):
        """Residuals ``(n_r,)`` and their Jacobian ``(n_r, 6 + n_angles)`` in (pose, angles)."""
        r = self._residuals(pose, x, *data)
        J_pose = jax.jacfwd(lambda p: self._residuals(p, x, *data))(pose)
        J_a = jax.vmap(lambda t: jax.jvp(lambda xx: self._residuals(pose, xx, *data), (x,), (t,))[1],
                       out_axes=1)(jnp.moveaxis(dx, -1, 0))
        return r, jnp.concatenate([J_pose, J_a], axis=1)

    # ------------------------------------------------------------------ data
    def _cloud(self, cloud):
        c = self.config
        if cloud is None:
            return np.zeros((c.max_points, 3)), np.zeros(c.max_points)
        P = np.asarray(cloud, float)
        if P.ndim != 2 or P.shape[1] != 3:
            raise CorrespondenceError(f"a range frame is an (n, 3) array of points (mm), got shape {P.shape}")
        P = P[np.isfinite(P).all(axis=1)]
        if len(P) == 0:
            raise CorrespondenceError("the range frame holds no (finite) point: the camera saw nothing of the "
                                      "hand in it; drop the frame or give its markers")
        if len(P) > c.max_points:
            P = P[np.random.default_rng(c.seed).choice(len(P), c.max_points, replace=False)]
        w = np.r_[np.ones(len(P)), np.zeros(c.max_points - len(P))]
        return np.concatenate([P, np.zeros((c.max_points - len(P), 3))]), w

    def _markers(self, markers):
        if markers is None:
            return np.zeros((1, 4), np.int64), np.zeros((1, 4)), np.zeros((1, 3)), np.zeros(1)
        ref, pos = (np.asarray(m, float) for m in markers)
        if ref.ndim != 2 or ref.shape[1] != 3 or pos.shape != ref.shape:
            raise CorrespondenceError(f"markers are (reference (m, 3), positions (m, 3)) in mm, got shapes "
                                      f"{ref.shape} and {pos.shape}")
        key = ref.tobytes()
        if key not in self._probes:
            try:
                p = jf.locate(self.model.hand.mesh, ref, tol=1e-3)
            except jf.MeshError as e:
                raise CorrespondenceError(f"markers off the hand model: {e}; give their positions on the "
                                          "undeformed skin (mm, model frame)") from None
            self._probes[key] = (np.asarray(p.nodes), np.asarray(p.weights))
        w = np.isfinite(pos).all(axis=1).astype(float)  # a marker lost in this frame weighs 0
        return (*self._probes[key], np.where(w[:, None] > 0, pos, 0.0), w)

    def _candidates(self, y, P):
        centre = y[self.tri].mean(axis=1)
        k = min(self.config.candidates, len(centre))
        return cKDTree(centre).query(P, k)[1].reshape(len(P), k)

    # ------------------------------------------------------------------ the fit
    def fit_frame(self, cloud=None, markers=None, start: FrameFit | None = None,
                  before: FrameFit | None = None) -> FrameFit:
        """Fit one frame: ``cloud (n, 3)`` (scanner frame, mm; non-finite rows, a range camera's
        holes, are left out; above ``max_points`` a random subset is used) and/or ``markers`` =
        ``(reference (m, 3), positions (m, 3))`` (model-frame rest positions; scanner-frame
        positions, NaN where lost: weight 0); ``start``: the last frame's fit (default: rest,
        identity pose); ``before``: the fit before it (for the constant-velocity prediction).

        Raises:
            CorrespondenceError: neither data, an empty frame, a cloud far from the hand, markers
                off the model.
        """
        if cloud is None and markers is None:
            raise CorrespondenceError("a frame needs a range cloud, markers or both")
        c, t0 = self.config, time.perf_counter()
        P, wP = self._cloud(cloud)
        mk = self._markers(markers)
        last, warm, data = fit_vector(start, len(self.names)), self._start(start), (P, wP, mk)
        if cloud is not None:
            self._check_near(last, warm[0], P[wP > 0])
        q = predicted(start, before) if c.predict else None
        state = None if q is None else self._state(q, warm, data)
        use_prediction = state is not None and "r" in state
        if not use_prediction:  # no prediction, or one the model cannot solve: from the last fit
            q, state = last.copy(), self._state(last, warm, data)
        if "r" not in state:
            raise CorrespondenceError(f"the hand model's solve failed at the starting angles "
                                      f"{np.degrees(last[6:]).round(2)} deg; start from a nearer fit (start=)")
        q, state, trials = self._lm(q, state, data, c.iterations)
        limit = c.restart_cost * max(int(wP.sum()) + 3 * int(mk[3].sum()), 1)
        restarted, won = state["cost"] > limit, -1
        if restarted:
            q, state, won, k = self._restart(q, state, last, use_prediction, warm, data, limit)
            trials += k
        return FrameFit(q[6:].copy(), q[:6].copy(), np.asarray(state["x"]) - self.model.hand.mesh.nodes,
                        *self._rms(state["r"], wP, mk, markers is not None), trials, time.perf_counter() - t0,
                        float(state["cost"]), bool(restarted), int(won), bool(use_prediction))

    def _rms(self, r, wP, mk, has_markers):
        """``(rms, marker_rms)`` (mm) of the residuals ``r``: the cloud's inliers, the markers'."""
        c = self.config
        dist = np.abs(r[: c.max_points][wP > 0]) * c.noise
        inl = dist[dist < c.robust * c.noise]
        mr = r[c.max_points:].reshape(-1, 3)[mk[3] > 0] * c.marker_noise
        return (float(np.sqrt(np.mean(inl ** 2))) if wP.sum() and len(inl) else float("nan"),
                float(np.sqrt(np.mean(np.sum(mr ** 2, axis=1)))) if has_markers else float("nan"))

    def _state(self, q, warm, data):
        """The evaluation (:meth:`_evaluate`) at ``q``, the solve warm-started from ``warm``."""
        dx, (x, u_D) = self._nodes(jnp.asarray(q[6:]), warm)
        return self._evaluate(q, x, dx, *data, u_D)

    def _lm(self, q, state, data, iterations):
        """Levenberg-Marquardt from ``q`` (its evaluation ``state``), at most ``iterations`` trials:
        ``(q, state, trials)``."""
        c = self.config
        lam, trials = 1e-3, 0
        while trials < iterations:
            r, J, w = state["r"], state["J"], state["w"]
            JW = J * w[:, None]
            H = JW.T @ J
            g = JW.T @ r
            if not c.pose:
                H[:6], H[:, :6], g[:6] = 0.0, 0.0, 0.0
                H[:6, :6] = np.eye(6)
            step = -np.linalg.solve(H + lam * np.diag(np.maximum(np.diag(H), 1e-12)), g)
            step *= min(1.0, c.max_turn / max(np.abs(step[6:]).max(initial=0.0), 1e-300))
            trials += 1
            q_new = q + step
            warm = (np.asarray(state["x"] - self.model.hand.mesh.nodes).reshape(-1), state["loads"])
            new = self._state(q_new, warm, data)
            if np.isfinite(new["cost"]) and new["cost"] <= state["cost"]:
                q, state, lam = q_new, new, max(lam / 5, 1e-7)
                small = np.abs(step[6:]).max(initial=0) < c.step_tol and np.abs(step[:3]).max() < c.step_tol \
                    and np.abs(step[3:6]).max() < 100 * c.step_tol
                if small:
                    break
            else:
                lam *= 8
        return q, state, trials

    def _restart(self, q, state, last, include_last, warm, data, limit):
        """The other starts (:func:`~examples.hand.starts.restart_starts` of the last fit ``last``) in
        turn after a first fit ``(q, state)`` ended above ``limit`` (the robust cost): each for
        ``restart_trials`` trials, one below the best cost so far carried on to convergence as the
        new best; stops at the first such fit at or below ``limit``. Returns ``(q, state, won, trials)``
        (``won``: the best start's index, -1 the first fit)."""
        c = self.config
        best, won, trials = (q, state), -1, 0
        for i, q0 in enumerate(restart_starts(last, self.names, c.restart_angles, c.restart_offsets, include_last)):
            s0 = self._state(q0, warm, data)
            if "r" not in s0:
                continue  # a start the model cannot reach is skipped
            q1, s1, k = self._lm(q0, s0, data, c.restart_trials)
            trials += k
            if s1["cost"] < best[1]["cost"]:
                q1, s1, k = self._lm(q1, s1, data, c.iterations)
                best, won, trials = (q1, s1), i, trials + k
                if s1["cost"] <= limit:
                    break
        return best[0], best[1], won, trials

    def linearise(self, q, cloud=None, markers=None, start: FrameFit | None = None):
        """The residuals ``(n_r,)`` (noise units; the cloud's padded to ``max_points``, then 3 per
        marker) and their exact Jacobian ``(n_r, 6 + n_angles)`` at ``q = (pose (6,), angles)``;
        data and ``start`` as for :meth:`fit_frame`."""
        state = self.evaluate(q, cloud, markers, start)
        return state["r"], state["J"]

    def evaluate(self, q, cloud=None, markers=None, start: FrameFit | None = None) -> dict:
        """:meth:`linearise`'s evaluation as a dict: ``r``, ``J``, the robust weights ``w (n_r,)``, the
        robust ``cost``, the nodes ``x (n_nodes, 3)`` (model frame, mm) and ``rms``, ``marker_rms`` (mm)."""
        q = np.asarray(q, float)
        P, wP = self._cloud(cloud)
        mk = self._markers(markers)
        dx, (x, u_D) = self._nodes(jnp.asarray(q[6:]), self._start(start))
        state = self._evaluate(q, x, dx, P, wP, mk, u_D)
        if "r" not in state:
            raise CorrespondenceError(f"the hand model's solve failed at the angles {np.degrees(q[6:]).round(2)} deg; "
                                      "start nearer (start=) or check the angles")
        state["rms"], state["marker_rms"] = self._rms(state["r"], wP, mk, markers is not None)
        return state

    def _check_near(self, q, u, P):
        """Refuse a cloud far from the hand at the starting estimate (pose ``q[:6]``, displacement ``u``)."""
        x = self.model.hand.mesh.nodes + np.asarray(u).reshape(-1, 3)
        y = np.asarray(_pose_apply(jnp.asarray(q[:6]), jnp.asarray(x)))
        d = np.median(cKDTree(y[self.tri].mean(axis=1)).query(P)[0])
        if d > self.config.far:
            raise CorrespondenceError(f"the range cloud lies {d:.1f} mm (median) from the hand model (more than "
                                      f"{self.config.far} mm): give it in the model's frame and unit (mm), or "
                                      "start from a nearer pose")

    def _start(self, fit: FrameFit | None):
        """The warm start ``(u, loads)`` of a fit (rest: zeros)."""
        if fit is None:
            return np.zeros(self.model.problem.n_dofs), self._loads(np.zeros_like(self._theta0["u_D"]))
        return fit.u.reshape(-1), self._loads(np.asarray(self.model.drive(dict(zip(self.names, fit.angles)))))

    def _loads(self, u_D):
        return {"u_D": np.asarray(u_D), "f": np.asarray(self._theta0["f"]),
                "traction": np.asarray(self._theta0["traction"])}

    def _evaluate(self, q, x, dx, P, wP, mk, u_D):
        """Residuals, Jacobian, robust weights and cost at ``q`` (NaN cost where the solve failed)."""
        x = np.asarray(x)
        if not np.isfinite(x).all():
            return {"cost": np.inf}
        cand = self._candidates(np.asarray(_pose_apply(jnp.asarray(q[:6]), jnp.asarray(x))), P)
        data = (jnp.asarray(P), jnp.asarray(cand), jnp.asarray(wP), *map(jnp.asarray, mk))
        r, J = (np.asarray(v) for v in self._linear(jnp.asarray(q[:6]), jnp.asarray(x), dx, data))
        k = self.config.robust
        w = 1.0 / (1.0 + (r / k) ** 2)
        loads = self._loads(u_D)
        return {"r": r, "J": J, "w": w, "cost": float(np.sum(k * k * np.log1p((r / k) ** 2))), "x": x,
                "loads": loads}

    def track(self, clouds=None, markers=None) -> list[FrameFit]:
        """Fit every frame in order, each from the last: ``clouds`` a sequence of ``(n_k, 3)`` (or
        None), ``markers`` ``(reference (m, 3), positions (n_frames, m, 3))`` (or None)."""
        if clouds is None and markers is None:
            raise CorrespondenceError("tracking needs range clouds, markers or both")
        n = len(clouds) if clouds is not None else len(markers[1])
        if clouds is not None and markers is not None and len(markers[1]) != n:
            raise CorrespondenceError(f"{n} range frames but markers in {len(markers[1])}: give both for every frame")
        fits = []
        for k in range(n):
            fits.append(self.fit_frame(None if clouds is None else clouds[k],
                                       None if markers is None else (markers[0], markers[1][k]),
                                       fits[-1] if fits else None, fits[-2] if len(fits) > 1 else None))
        return fits
