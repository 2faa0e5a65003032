"""The differentiable correspondence-free fit: the model's boundary against the clouds.

For each frame, the misfit of the deformed model to the cloud sums robust (Cauchy) penalties of
- every boundary point's distance to the model's boundary (soft minimum over its facets: point to
  segment of the outline in 2D, point to triangle of the surface in 3D, where every point of a
  range cloud is a boundary point);
- (2D) every surface sample's distance outside the model (zero inside);
- (optional) every tracked point's distance to its model position (points with identities, e.g.
  a bundle's points.csv beside its clouds: extra data, :func:`with_labelled`);
- every seen boundary node's distance to the nearest boundary point (soft minimum; a small weight:
  it keeps parts of the model's boundary from wandering where no point was seen; in 3D only the
  nodes a camera saw in the reference frame, :func:`refine.correspond.geometry.seen_nodes`).
The penalties are in units of squared noise-weighted residuals, so a modulus field's smoothing
weight means what it means in the labelled diagnosis. The misfit is minimised over the grips'
motion of every frame AND the model's parameters (any parametrisation of :mod:`refine.model`)
with one adjoint solve per frame per gradient (:func:`refine.optimize.lbfgsb`).

No optimal-transport cost: the outline and the surface are sampled at different densities, and
a transport plan would match the densities (ott-jax solves that problem), not the shapes.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import jax
import jax.numpy as jnp
import numpy as np

from refine.correspond.geometry import (candidate_distances, facet_distances, inside, on_boundary, point_spacing,
                                        seen_nodes, shortlist, softmin)
from refine.correspond.model import CloudModel
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
        shortlist: candidate facets per boundary point (the nearest by centroid) where the model
            has more than four times as many (a 3D surface's triangles): the misfit then costs k
            facets per point, not all; the 2D outline's few dozen segments are all taken.
    """

    noise: float = 0.05
    robust: float = 3.0
    node_weight: float = 0.2
    holdout: float = 0.25
    seed: int = 0
    shortlist: int = 32


def compiled_settings(config: FitConfig) -> FitConfig:
    """The settings a compiled misfit depends on: ``config`` without the hold-out's share and seed
    (they only split the data), so that fitters kept per settings serve every seed."""
    return replace(config, seed=0, holdout=0.0)


@dataclass(frozen=True, eq=False)
class FrameData:
    """Clouds of several frames, split into boundary points (the outline in 2D, every point of a
    range cloud in 3D) and interior points (2D: samples of the sheet's surface; none in 3D), padded
    to common sizes (weight 0 marks padding), so that one compiled misfit serves every frame.

    Attributes:
        boundary: ``(n_frames, n_b, dim)``; w_boundary ``(n_frames, n_b)``.
        interior: ``(n_frames, n_i, dim)``; w_interior ``(n_frames, n_i)``.
        spacing: median spacing of the boundary points (length).
        node_weights: ``(n_boundary_nodes,)`` which of the model's boundary nodes (in
            ``CloudModel.boundary_nodes`` order) the nodes-to-cloud term pulls (1) or leaves (0);
            None: all of them.
        labelled: ``(n_frames, n_l, dim)`` positions of tracked points (with identities) or None;
            w_labelled ``(n_frames, n_l)`` (0 where a point was lost); probe: ``(nodes (n_l, k),
            weights (n_l, k))`` where each tracked point lies in the model (its cell's nodes and
            shape-function values at its reference position).
        candidates: ``(n_frames, n_b, k)`` each boundary point's candidate facets
            (:func:`refine.correspond.geometry.shortlist`) or None (all facets).
    """

    boundary: np.ndarray
    w_boundary: np.ndarray
    interior: np.ndarray
    w_interior: np.ndarray
    spacing: float
    node_weights: np.ndarray | None = None
    labelled: np.ndarray | None = None
    w_labelled: np.ndarray | None = None
    probe: tuple | None = None
    candidates: np.ndarray | None = None

    def frames(self, idx) -> FrameData:
        """The data of the frames ``idx`` (indices into this record)."""
        idx = np.atleast_1d(idx)
        lab = None if self.labelled is None else (self.labelled[idx], self.w_labelled[idx])
        return replace(self, boundary=self.boundary[idx], w_boundary=self.w_boundary[idx],
                       interior=self.interior[idx], w_interior=self.w_interior[idx],
                       candidates=None if self.candidates is None else self.candidates[idx],
                       **({} if lab is None else {"labelled": lab[0], "w_labelled": lab[1]}))

    def arrays(self):
        """The per-frame arrays the compiled misfit maps over (the tracked points' last, if any)."""
        extra = () if self.labelled is None else (self.labelled, self.w_labelled)
        return tuple(jnp.asarray(a) for a in (self.boundary, self.w_boundary, self.interior, self.w_interior, *extra))

    def seen_by(self, model: CloudModel, reference: np.ndarray, tol: float) -> FrameData:
        """The same data whose nodes-to-cloud term pulls only the boundary nodes within ``tol``
        (length) of the ``reference`` cloud (frame 0): those a camera saw."""
        w = seen_nodes(model.mesh.nodes[model.boundary_nodes], reference, tol).astype(float)
        return replace(self, node_weights=w)


def with_labelled(data: FrameData, model: CloudModel, reference, displacements) -> FrameData:
    """``data`` with tracked points as extra data: ``reference (n_l, dim)`` their positions in frame
    0, ``displacements (n_frames, n_l, dim)`` in frames 1.. (NaN where lost), for the frames of
    ``data`` (frame 0 first). Raises :class:`CorrespondenceError` for points outside the model or a
    frame count that differs from the clouds'."""
    import jaxfem as jf

    X = np.asarray(reference, float)
    U = np.asarray(displacements, float)
    if len(U) + 1 != len(data.boundary):
        raise CorrespondenceError(f"the tracked points have {len(U)} deformed frames but the clouds "
                                  f"{len(data.boundary) - 1}; both must cover the same frames")
    try:
        probe = jf.locate(model.mesh, X, tol=1e-3)
    except jf.MeshError as e:
        raise CorrespondenceError(f"tracked points outside the model: {e}") from None
    pos = np.concatenate([X[None], X[None] + U])
    seen = np.isfinite(pos).all(axis=2)
    return replace(data, labelled=np.where(seen[..., None], pos, 0.0), w_labelled=seen.astype(float),
                   probe=(probe.nodes, probe.weights))


def split_frames(clouds, config: FitConfig) -> tuple[FrameData, FrameData]:
    """Split every frame's cloud into boundary and interior points and hold a random share of the
    boundary points out: returns ``(train, held)``, both over all frames (frame 0 included)."""
    rng = np.random.default_rng(config.seed)
    train_o, held_o, surf = [], [], []
    dims = {np.shape(c)[-1] for c in clouds}
    if len(dims) != 1 or not dims <= {2, 3}:
        raise CorrespondenceError(f"every frame's cloud must hold points of one dimension, 2 or 3; got {sorted(dims)}")
    for k, cloud in enumerate(clouds):
        cloud = np.asarray(cloud, float)
        if len(cloud) == 0:
            raise CorrespondenceError(f"frame {k} has an empty cloud; leave the frame out or give its points")
        if not np.all(np.isfinite(cloud)):
            raise CorrespondenceError(f"frame {k}'s cloud has NaN or inf coordinates; leave unseen points out")
        on = on_boundary(cloud, 4 * config.noise)
        if on.sum() < 8:
            where = "lie on an outline" if cloud.shape[1] == 2 else "are in the range cloud"
            raise CorrespondenceError(f"frame {k}: only {int(on.sum())} points {where}; the fit needs the object's "
                                      "boundary sampled densely (a point every few noise levels)")
        o = cloud[on][rng.permutation(int(on.sum()))]
        n_held = int(round(config.holdout * len(o)))
        held_o.append(o[:n_held])
        train_o.append(o[n_held:])
        surf.append(cloud[~on])
    spacing = float(np.median([point_spacing(o) for o in train_o]))
    empty = np.zeros((0, dims.pop()))
    return (_padded(train_o, surf, spacing), _padded(held_o, [empty] * len(held_o), spacing))


def _padded(boundary, interior, spacing) -> FrameData:
    def pad(parts):
        n = max(1, max(len(p) for p in parts))
        a, w = np.zeros((len(parts), n, parts[0].shape[1])), np.zeros((len(parts), n))
        for k, p in enumerate(parts):
            a[k, : len(p)], w[k, : len(p)] = p, 1.0
            a[k, len(p):] = p[0] if len(p) else 0.0  # padding sits on a real point: finite distances
        return a, w

    (o, wo), (s, ws) = pad(boundary), pad(interior)
    return FrameData(o, wo, s, ws, spacing)


def cauchy(r, c: float):
    """Robust penalty ``c^2 log(1 + r^2 / c^2)`` (about r^2 for small r)."""
    return c * c * jnp.log1p((r / c) ** 2)


def frame_misfit(x, facets, bnodes, w_nodes, boundary, w_b, interior, w_i, labelled=None, w_l=None, *,
                 config: FitConfig, spacing: float, probe=None, candidates=None):
    """The misfit of one frame's deformed node positions ``x (n_nodes, dim)`` to its cloud
    (scalar); ``facets`` the model's boundary facets, ``bnodes`` its boundary nodes and
    ``w_nodes`` their weights in the nodes-to-cloud term; ``labelled``, ``w_l`` and ``probe`` the
    tracked points (:class:`FrameData`), if any; ``candidates (n_b, k)`` the boundary points'
    shortlists of facets (None: all facets)."""
    s = config.noise
    D_o = facet_distances(boundary, x, facets) if candidates is None else candidate_distances(boundary, x, facets,
                                                                                              candidates)
    d_o = softmin(D_o, 0.25 * s)
    total = jnp.sum(w_b * cauchy(d_o / s, config.robust))
    if facets.shape[1] == 2:  # a sheet's surface samples lie inside its outline
        A, B = x[facets[:, 0]], x[facets[:, 1]]
        d_s = jnp.min(facet_distances(interior, x, facets), axis=1)
        d_s = jnp.where(inside(interior, A, B), 0.0, d_s)
        total = total + jnp.sum(w_i * cauchy(d_s / s, config.robust))
    scale = jnp.maximum(s, spacing)
    D = jnp.sqrt(jnp.sum((x[bnodes][:, None] - boundary[None]) ** 2, axis=-1) + 1e-18) + 1e6 * (1.0 - w_b)[None]
    d_n = softmin(D, 0.25 * scale)
    n_ratio = jnp.sum(w_b) / jnp.sum(w_nodes)  # the nodes' term counts as much as the points', times its weight
    total = total + config.node_weight * n_ratio * jnp.sum(w_nodes * cauchy(d_n / scale, config.robust))
    if labelled is not None:
        model_at = jnp.einsum("pk,pkd->pd", probe[1], x[probe[0]])
        d_l = jnp.sqrt(jnp.sum((model_at - labelled) ** 2, axis=1) + 1e-18)
        total = total + jnp.sum(w_l * cauchy(d_l / s, config.robust))
    return total


def held_error(model: CloudModel, positions: np.ndarray, held: FrameData, cap: float) -> np.ndarray:
    """Prediction error per frame: the RMS distance of the held-out boundary points to the model's
    boundary at ``positions (n_frames, n_nodes, dim)`` (length), ``(n_frames,)``; each distance
    capped at ``cap`` (a surface sample taken for an outline point must not dominate)."""
    out = []
    for x, o, w in zip(positions, held.boundary, held.w_boundary):
        d = np.minimum(model.boundary_distances(o, x), cap)
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
        """Node positions ``(n_frames, n_nodes, dim)`` for grips ``Q`` and parameters ``zp``."""
        return jnp.asarray(self.model.mesh.nodes)[None] + self.model._solve_frames(self.theta(zp), Q, start)

    def value(self, Q, zp, arrays, start, spacing, reg_weight=1.0, w_nodes=None, probe=None, candidates=None):
        """Misfit of the frames in ``arrays`` (:meth:`FrameData.arrays`) plus ``reg_weight`` times
        the parametrisation's regulariser (an argument: a new weight compiles nothing);
        ``w_nodes`` the boundary nodes' weights (:attr:`FrameData.node_weights`; None: all 1),
        ``probe`` the tracked points' (:attr:`FrameData.probe`; with their arrays in ``arrays``),
        ``candidates`` the boundary points' facet shortlists (:attr:`FrameData.candidates`)."""
        m, cfg = self.model, self.config
        x = self.positions(Q, zp, start)
        facets, bn = jnp.asarray(m.facets), jnp.asarray(m.boundary_nodes)
        w_n = jnp.ones(len(m.boundary_nodes)) if w_nodes is None else w_nodes
        cand = jnp.zeros((len(x), 0), int) if candidates is None else candidates  # mapped over frames either way
        per = jax.vmap(lambda xf, c, *a: frame_misfit(xf, facets, bn, w_n, *a, config=cfg, spacing=spacing,
                                                      probe=probe, candidates=None if candidates is None else c)
                       )(x, cand, *arrays)
        return jnp.sum(per) + (0.0 if self.param is None else reg_weight * self.param.regularization(zp))

    def fit(self, data: FrameData, Q0, zp=None, start=None, joint: bool = False, maxiter: int = 100,
            reg_weight: float = 1.0):
        """Minimise the misfit of ``data``'s frames over their grips (and, with ``joint``, over the
        parameters too) by L-BFGS-B with adjoint gradients (:func:`refine.optimize.lbfgsb`).

        Args:
            data: the frames to fit; Q0 ``(n_frames, n_grips, grip_dof)`` their initial grips; zp the
                parameters (default: the parametrisation's start); start the equilibrium
                ``(u, q)`` before the first frame (default: the reference); reg_weight multiplies
                the regulariser.
        Returns ``(Q, zp, RefineResult)``.
        """
        from refine.optimize.lbfgsb import lbfgsb

        Q0 = np.asarray(Q0, float)
        shape = (len(data.boundary), self.model.n_grips, self.model.grip_dof)
        if Q0.shape != shape:
            raise CorrespondenceError(f"Q0 must have shape {shape}, got {Q0.shape}")
        zp = self.zp0 if zp is None else np.asarray(zp, float)
        start = self.model.start(start)
        Q, zp_new = Q0, zp
        for _ in range(3):  # a facet shortlist made where the fit starts holds unless the model moved far
            if self.uses_shortlist:
                data = replace(data, candidates=self.shortlists(data, Q, zp_new, start))
            objective = _Objective(self, data, Q, zp_new, start, joint, reg_weight)
            res = lbfgsb(objective, maxiter=maxiter)
            Q, zp_new = objective.param.split(res.values["z"])
            if not self.uses_shortlist or self.shortlists_hold(data, Q, zp_new, start):
                break
        return np.asarray(Q), np.asarray(zp_new), res

    @property
    def uses_shortlist(self) -> bool:
        """Whether the boundary points see a shortlist of facets (:attr:`FitConfig.shortlist`)."""
        k = self.config.shortlist
        return bool(k) and len(self.model.facets) > 4 * k

    def shortlists(self, data: FrameData, Q, zp, start) -> np.ndarray:
        """``(n_frames, n_b, k)``: each boundary point's nearest facets by centroid at the model's
        positions for grips ``Q`` and parameters ``zp``."""
        x = np.asarray(self._positions(jnp.asarray(Q), jnp.asarray(zp), start))
        return np.stack([shortlist(b, xf, self.model.facets, self.config.shortlist) for b, xf in zip(data.boundary, x)])

    def shortlists_hold(self, data: FrameData, Q, zp, start) -> bool:
        """True when every boundary point's nearest facet at the fitted positions is on its
        shortlist (to a tenth of the noise): else the fit is made again with new shortlists."""
        x = np.asarray(self._positions(jnp.asarray(Q), jnp.asarray(zp), start))
        facets = jnp.asarray(self.model.facets)
        for b, c, w, xf in zip(data.boundary, data.candidates, data.w_boundary, x):
            listed = np.asarray(candidate_distances(jnp.asarray(b), jnp.asarray(xf), facets, jnp.asarray(c)))
            listed = listed.min(axis=1)
            if np.any((w > 0) & (listed > self.model.boundary_distances(b, xf) + 0.1 * self.config.noise)):
                return False
        return True


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
        self.w_nodes = None if data.node_weights is None else jnp.asarray(data.node_weights)
        self.probe = None if data.probe is None else tuple(jnp.asarray(a) for a in data.probe)
        self.candidates = None if data.candidates is None else jnp.asarray(data.candidates)
        self.reg_weight = reg_weight
        self.param = _Joint(Q0, zp, joint, fitter.param)
        self.n_forward = self.n_gradient = 0

    def value_and_grad(self, z):
        p, f = self.param, self.fitter
        Q = jnp.reshape(z[: p.n_q], p.Q0.shape)
        if not p.joint:
            v, gQ = f._grips_grad(Q, jnp.asarray(p.zp), self.arrays, self.start, self.spacing, self.reg_weight,
                                  self.w_nodes, self.probe, self.candidates)
            return v, jnp.ravel(gQ)
        v, (gQ, gp) = f._joint_grad(Q, z[p.n_q:], self.arrays, self.start, self.spacing, self.reg_weight,
                                    self.w_nodes, self.probe, self.candidates)
        return v, jnp.concatenate([jnp.ravel(gQ), gp])
