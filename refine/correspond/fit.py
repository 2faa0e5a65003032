"""The differentiable correspondence-free fit: the model's outline against the clouds.

For each frame, the misfit of the deformed model to the cloud sums robust (Cauchy) penalties of
- every outline point's distance to the model's outline (point-to-segment, soft minimum);
- every surface sample's distance outside the model (zero inside);
- every outline node's distance to the nearest outline point (soft minimum; a small weight: it
  keeps parts of the model's outline from wandering where no point was seen).
The penalties are in units of squared noise-weighted residuals, so a modulus field's smoothing
weight means what it means in the labelled diagnosis. The misfit is minimised over the grips'
motion of every frame AND the model's parameters (any parametrisation of :mod:`refine.model`)
with one adjoint solve per frame per gradient (:func:`refine.optimize.lbfgsb`).

No optimal-transport cost: the outline and the surface are sampled at different densities, and
a transport plan would match the densities (ott-jax solves that problem), not the shapes.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from refine.correspond.geometry import inside, point_spacing, segment_distances, softmin, split_outline
from refine.correspond.model import GRIP_DOF, CloudModel
from refine.exceptions import CorrespondenceError


@dataclass(frozen=True)
class FitConfig:
    """Settings of the correspondence-free fit (data).

    Attributes:
        noise: standard deviation of a point's position (length); the distances' scale.
        robust: Cauchy scale of a residual, in noise units (larger residuals weigh less).
        node_weight: weight of the nodes-to-cloud term relative to the points-to-model terms.
        holdout: share of each frame's outline points held out of every fit (prediction error).
        seed: seeds the hold-out.
    """

    noise: float = 0.05
    robust: float = 3.0
    node_weight: float = 0.2
    holdout: float = 0.25
    seed: int = 0


@dataclass(frozen=True, eq=False)
class FrameData:
    """Clouds of several frames, split into outline and surface points and padded to common sizes
    (weight 0 marks padding), so that one compiled misfit serves every frame.

    Attributes:
        outline: ``(n_frames, n_o, 2)``; w_outline ``(n_frames, n_o)``.
        surface: ``(n_frames, n_s, 2)``; w_surface ``(n_frames, n_s)``.
        spacing: median spacing of the outline points (length).
    """

    outline: np.ndarray
    w_outline: np.ndarray
    surface: np.ndarray
    w_surface: np.ndarray
    spacing: float

    def frames(self, idx) -> FrameData:
        """The data of the frames ``idx`` (indices into this record)."""
        idx = np.atleast_1d(idx)
        return FrameData(self.outline[idx], self.w_outline[idx], self.surface[idx], self.w_surface[idx], self.spacing)

    def arrays(self):
        return tuple(jnp.asarray(a) for a in (self.outline, self.w_outline, self.surface, self.w_surface))


def split_frames(clouds, config: FitConfig) -> tuple[FrameData, FrameData]:
    """Split every frame's cloud into outline and surface points and hold a random share of the
    outline points out: returns ``(train, held)``, both over all frames (frame 0 included)."""
    rng = np.random.default_rng(config.seed)
    train_o, held_o, surf = [], [], []
    for k, cloud in enumerate(clouds):
        cloud = np.asarray(cloud, float)
        if len(cloud) == 0:
            raise CorrespondenceError(f"frame {k} has an empty cloud; leave the frame out or give its points")
        if not np.all(np.isfinite(cloud)):
            raise CorrespondenceError(f"frame {k}'s cloud has NaN or inf coordinates; leave unseen points out")
        on = split_outline(cloud, 4 * config.noise)
        if on.sum() < 8:
            raise CorrespondenceError(f"frame {k}: only {int(on.sum())} points lie on an outline; the fit needs the "
                                      "object's outline sampled densely (a point every few noise levels)")
        o = cloud[on][rng.permutation(int(on.sum()))]
        n_held = int(round(config.holdout * len(o)))
        held_o.append(o[:n_held])
        train_o.append(o[n_held:])
        surf.append(cloud[~on])
    spacing = float(np.median([point_spacing(o) for o in train_o]))
    empty = np.zeros((0, 2))
    return (_padded(train_o, surf, spacing), _padded(held_o, [empty] * len(held_o), spacing))


def _padded(outline, surface, spacing) -> FrameData:
    def pad(parts):
        n = max(1, max(len(p) for p in parts))
        a, w = np.zeros((len(parts), n, 2)), np.zeros((len(parts), n))
        for k, p in enumerate(parts):
            a[k, : len(p)], w[k, : len(p)] = p, 1.0
            a[k, len(p):] = p[0] if len(p) else 0.0  # padding sits on a real point: finite distances
        return a, w

    (o, wo), (s, ws) = pad(outline), pad(surface)
    return FrameData(o, wo, s, ws, spacing)


def cauchy(r, c: float):
    """Robust penalty ``c^2 log(1 + r^2 / c^2)`` (about r^2 for small r)."""
    return c * c * jnp.log1p((r / c) ** 2)


def frame_misfit(x, segments, bnodes, outline, w_o, surface, w_s, config: FitConfig, spacing: float):
    """The misfit of one frame's deformed node positions ``x (n_nodes, 2)`` to its cloud (scalar)."""
    s = config.noise
    A, B = x[segments[:, 0]], x[segments[:, 1]]
    d_o = softmin(segment_distances(outline, A, B), 0.25 * s)
    total = jnp.sum(w_o * cauchy(d_o / s, config.robust))
    d_s = jnp.min(segment_distances(surface, A, B), axis=1)
    d_s = jnp.where(inside(surface, A, B), 0.0, d_s)
    total = total + jnp.sum(w_s * cauchy(d_s / s, config.robust))
    scale = jnp.maximum(s, spacing)
    D = jnp.sqrt(jnp.sum((x[bnodes][:, None] - outline[None]) ** 2, axis=-1) + 1e-18) + 1e6 * (1.0 - w_o)[None]
    d_n = softmin(D, 0.25 * scale)
    n_ratio = jnp.sum(w_o) / len(bnodes)  # the nodes' term counts as much as the points' term, times its weight
    return total + config.node_weight * n_ratio * jnp.sum(cauchy(d_n / scale, config.robust))


def held_error(model: CloudModel, positions: np.ndarray, held: FrameData, cap: float) -> np.ndarray:
    """Prediction error per frame: the RMS distance of the held-out outline points to the model's
    outline at ``positions (n_frames, n_nodes, 2)`` (length), ``(n_frames,)``; each distance capped
    at ``cap`` (a surface sample taken for an outline point must not dominate)."""
    out = []
    for x, o, w in zip(positions, held.outline, held.w_outline):
        A, B = x[model.segments[:, 0]], x[model.segments[:, 1]]
        d = np.minimum(np.asarray(segment_distances(jnp.asarray(o), jnp.asarray(A), jnp.asarray(B))).min(axis=1), cap)
        out.append(float(np.sqrt(np.sum(w * d * d) / max(w.sum(), 1))))
    return np.array(out)


class Fitter:
    """The clouds' misfit of a model under one parametrisation, compiled once and reused for every
    window of frames of the same length (data, grips and start are arguments, not constants).

    Args:
        model: the :class:`CloudModel`.
        config: the fit's settings.
        param: a parametrisation of :mod:`refine.model` (``ModulusField``, ``RegionModuli``...) or
            None; it applies to the initial model's parameters.
    """

    def __init__(self, model: CloudModel, config: FitConfig, param=None):
        self.model, self.config, self.param = model, config, param
        self.base = model.params()
        self.zp0 = np.zeros(0) if param is None else np.asarray(param.z0, float)
        self._grips_grad = jax.jit(jax.value_and_grad(self.value, argnums=0))
        self._joint_grad = jax.jit(jax.value_and_grad(self.value, argnums=(0, 1)))
        self._positions = jax.jit(self.positions)

    def theta(self, zp):
        return self.base if self.param is None else self.param.apply(self.base, zp)

    def positions(self, Q, zp, start):
        """Node positions ``(n_frames, n_nodes, 2)`` for grips ``Q`` and parameters ``zp``."""
        return jnp.asarray(self.model.mesh.nodes)[None] + self.model._solve_frames(self.theta(zp), Q, start)

    def value(self, Q, zp, arrays, start, spacing, reg_weight=1.0):
        """Misfit of the frames in ``arrays`` (:meth:`FrameData.arrays`) plus ``reg_weight`` times
        the parametrisation's regulariser (an argument: a new weight compiles nothing)."""
        m, cfg = self.model, self.config
        x = self.positions(Q, zp, start)
        segs, bn = jnp.asarray(m.segments), jnp.asarray(m.boundary_nodes)
        per = jax.vmap(lambda xf, of, wof, sf, wsf: frame_misfit(xf, segs, bn, of, wof, sf, wsf, cfg, spacing))(
            x, *arrays)
        return jnp.sum(per) + (0.0 if self.param is None else reg_weight * self.param.regularization(zp))

    def fit(self, data: FrameData, Q0, zp=None, start=None, joint: bool = False, maxiter: int = 100,
            reg_weight: float = 1.0):
        """Minimise the misfit of ``data``'s frames over their grips (and, with ``joint``, over the
        parameters too) by L-BFGS-B with adjoint gradients (:func:`refine.optimize.lbfgsb`).

        Args:
            data: the frames to fit; Q0 ``(n_frames, n_grips, 3)`` their initial grips; zp the
                parameters (default: the parametrisation's start); start the equilibrium
                ``(u, q)`` before the first frame (default: the reference); reg_weight multiplies
                the regulariser.
        Returns ``(Q, zp, RefineResult)``.
        """
        from refine.optimize.lbfgsb import lbfgsb

        Q0 = np.asarray(Q0, float)
        if Q0.shape != (len(data.outline), self.model.n_grips, GRIP_DOF):
            raise CorrespondenceError(f"Q0 must have shape ({len(data.outline)}, {self.model.n_grips}, {GRIP_DOF}), "
                                      f"got {Q0.shape}")
        zp = self.zp0 if zp is None else np.asarray(zp, float)
        objective = _Objective(self, data, Q0, zp, self.model.start(start), joint, reg_weight)
        res = lbfgsb(objective, maxiter=maxiter)
        Q, zp_new = objective.param.split(res.values["z"])
        return np.asarray(Q), np.asarray(zp_new), res


class _Joint:
    """The unknowns of a fit: the grips' motion of every fitted frame, then (in a joint fit) the
    parametrisation's z."""

    def __init__(self, Q0, zp, joint: bool, inner):
        self.Q0, self.zp, self.joint, self.inner = Q0, zp, joint, inner
        self.n_q = Q0.size
        self.z0 = np.concatenate([Q0.ravel(), zp if joint else np.zeros(0)])

    def split(self, z):
        z = np.asarray(z)
        return z[: self.n_q].reshape(self.Q0.shape), (z[self.n_q:] if self.joint else self.zp)

    def values(self, z) -> dict:
        Q, zp = self.split(z)
        out = {"grips": Q}
        if self.inner is not None and self.joint:
            out.update(self.inner.values(zp))
        return out


class _Objective:
    """What :func:`refine.optimize.lbfgsb` minimises: a :class:`Fitter`'s misfit on given frames as a
    function of one vector z (the grips, and in a joint fit the parameters)."""

    def __init__(self, fitter: Fitter, data: FrameData, Q0, zp, start, joint: bool, reg_weight: float):
        self.fitter, self.arrays, self.start, self.spacing = fitter, data.arrays(), start, data.spacing
        self.reg_weight = reg_weight
        self.param = _Joint(Q0, zp, joint, fitter.param)
        self.n_forward = self.n_gradient = 0

    def value_and_grad(self, z):
        p, f = self.param, self.fitter
        Q = jnp.reshape(z[: p.n_q], p.Q0.shape)
        if not p.joint:
            v, gQ = f._grips_grad(Q, jnp.asarray(p.zp), self.arrays, self.start, self.spacing, self.reg_weight)
            return v, jnp.ravel(gQ)
        v, (gQ, gp) = f._joint_grad(Q, z[p.n_q:], self.arrays, self.start, self.spacing, self.reg_weight)
        return v, jnp.concatenate([jnp.ravel(gQ), gp])
