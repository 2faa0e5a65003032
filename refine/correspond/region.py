"""The parametric refit of the regions a modulus field located from unlabelled clouds.

A total-variation field smears a small stiff inclusion over more cells at a lower ratio, and from
outline-only (or surface-only) data it also puts small compensating regions where the boundary
moves, e.g. a cell at a free edge beside the inclusion: the boundary's shape there is changed as
well by the inclusion as by that cell. The field locates; this module then fits each region as a
ball (a disc in 2D) of its own modulus, its centre, radius and ratio together with every frame's
grips by exact (adjoint) gradients, and keeps a region only where the misfit drops by more than
the Bayesian information criterion's penalty, ``(dim + 2) ln n`` for ``n`` boundary points: a
region the data cannot tell from the smearing of another is rejected, with its numbers reported.
Standard errors combine the misfit's curvature, the residuals' observed scatter and the
discretisation (a refit on a coarser mesh); a radius or ratio they leave undetermined is reported
as not identified (:mod:`refine.correspond.region_errors`).
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from refine.correspond.fit import FitConfig, Fitter, FrameData, compiled_settings
from refine.correspond.model import CloudModel


@dataclass(frozen=True, eq=False)
class SoftBalls:
    """Balls (discs in 2D) of their own modulus: a cell's modulus is multiplied by
    ``exp(sum_k log(ratio_k) s_k)``, ``s_k = sigmoid((r_k - |c - centre_k|) / width)`` at its
    centroid ``c``: smooth in the centre, radius and ratio, so that exact gradients move them.

    z holds per ball its centre divided by ``scale`` (``dim`` unknowns), log radius and log ratio
    (absolute, not changes: a new start compiles nothing).

    Args:
        centroids: ``(n_cells, dim)`` the cells' centroids (length).
        E0: reference modulus (stress).
        n_balls: how many balls.
        width: the indicator's blending length (length; about half a cell).
        scale: length unit of the centres' unknowns.
    """

    centroids: np.ndarray
    E0: float
    n_balls: int
    width: float
    scale: float

    @property
    def dim(self) -> int:
        return self.centroids.shape[1]

    @property
    def size(self) -> int:
        return self.n_balls * (self.dim + 2)

    @property
    def z0(self):
        return jnp.zeros(self.size)

    def z_of(self, centre, radius, ratio) -> np.ndarray:
        """The unknowns of balls of centres ``(n, dim)``, radii ``(n,)`` and ratios ``(n,)``."""
        c = np.atleast_2d(np.asarray(centre, float)) / self.scale
        return np.concatenate([c, np.log(np.atleast_1d(radius))[:, None], np.log(np.atleast_1d(ratio))[:, None]],
                              1).ravel()

    def log_factor(self, z):
        """log of each cell's modulus factor, ``(n_cells,)``."""
        p = jnp.reshape(jnp.asarray(z), (self.n_balls, self.dim + 2))
        d = jnp.sqrt(jnp.sum((jnp.asarray(self.centroids)[:, None] - p[None, :, : self.dim] * self.scale) ** 2,
                             axis=-1) + 1e-18)
        s = jax.nn.sigmoid((jnp.exp(p[None, :, self.dim]) - d) / self.width)
        return s @ p[:, self.dim + 1]

    def apply(self, theta, z):
        return {**theta, "E": theta["E"] * jnp.exp(self.log_factor(z))}

    def regularization(self, z):
        return 0.0

    def values(self, z) -> dict:
        p = np.reshape(np.asarray(z, float), (self.n_balls, self.dim + 2))
        return {f"ball{k + 1}": {"centre": (q[: self.dim] * self.scale).tolist(), "radius": float(np.exp(q[self.dim])),
                                 "ratio": float(np.exp(q[self.dim + 1]))} for k, q in enumerate(p)}


def ball_fitter(model: CloudModel, config: FitConfig, n_balls: int) -> Fitter:
    """The :class:`Fitter` of ``n_balls`` soft balls on ``model`` (kept on the model: a second
    refit compiles nothing)."""
    cache = model.__dict__.setdefault("_ball_fitters", {})
    config = compiled_settings(config)
    key = (config, n_balls)
    if key not in cache:
        cell = float(np.mean(model.mesh.volumes())) ** (1.0 / model.dim)
        cache[key] = Fitter(model, config, SoftBalls(model.mesh.centroids(), model.experiment.E, n_balls,
                                                     width=0.5 * cell, scale=cell))
    return cache[key]


def refit_regions(model: CloudModel, config: FitConfig, data: FrameData, Q, candidates: list,
                  maxiter: int = 80) -> dict:
    """Refit the field's regions as balls over every frame of ``data`` and keep those the BIC
    accepts (module docstring).

    Args:
        model: the :class:`CloudModel`; config: the fit's settings.
        data: the training clouds of the deformed frames (frame 0 left out), in order.
        Q: ``(n_frames, n_grips, grip_dof)`` the grips the follow fitted (the start).
        candidates: the field's regions, strongest first (dicts with ``cause``, ``centroid``,
            ``relative_elasticity``, ``area``: :func:`refine.correspond.follow.field_findings`).

    Returns a dict: ``regions`` (kept: cause, centroid, radius, relative_elasticity, and
    standard errors ``centroid_se``, ``radius_se``, ``relative_elasticity_se``; radius and
    ratio None where not identified, with ``radius_fitted``, ``identified``, ``se_parts``,
    ``trade_off``: :func:`refine.correspond.region_errors.described`), ``rejected``
    (the candidates the BIC turned down, with the misfit drop and the penalty), ``misfits`` (the
    misfit with 0, 1, ... balls), ``bic_penalty`` per ball, ``grips`` of the best fit and, where a
    ball was kept, ``positions (n_frames, n_nodes, dim)`` every node in every frame under it.
    """
    Q = np.asarray(Q, float)
    n = float(np.sum(data.w_boundary))
    penalty = (model.dim + 2) * np.log(n)
    base = ball_fitter(model, config, 1)
    Q0, _, res0 = base.fit(data, Q, base.param.z_of(candidates[0]["centroid"], 1.0, 1.0), maxiter=maxiter)
    misfits, kept, rejected, z = [float(res0.error)], [], [], np.zeros(0)
    best_Q = Q0
    for cand in candidates:
        fitter = ball_fitter(model, config, len(kept) + 1)
        z_start = np.concatenate([z, _start(fitter.param, cand, model.dim)])
        Qk, zk, res = fitter.fit(data, best_Q, z_start, joint=True, maxiter=maxiter)
        drop = misfits[-1] - float(res.error)
        if drop > penalty:
            kept.append(cand)
            misfits.append(float(res.error))
            z, best_Q = zk, Qk
        else:
            rejected.append({**cand, "misfit_drop": drop, "bic_penalty": penalty})
    out = {"regions": [], "rejected": rejected, "misfits": misfits, "bic_penalty": penalty, "grips": best_Q.tolist()}
    if kept:
        fitter = ball_fitter(model, config, len(kept))
        out["regions"] = _described(fitter, config, data, best_Q, z, maxiter)
        out["positions"] = np.asarray(fitter._positions(jnp.asarray(best_Q), jnp.asarray(z), model.start(None)))
    return out


def _start(param: SoftBalls, cand: dict, dim: int) -> np.ndarray:
    """A ball's start from a field region: its centroid, the radius of its area (volume), its
    ratio at least 2 (a TV field's peak is well below a small region's ratio)."""
    size = cand["area"]
    radius = np.sqrt(size / np.pi) if dim == 2 else (3.0 * size / (4.0 * np.pi)) ** (1.0 / 3.0)
    r = cand["relative_elasticity"]
    ratio = max(r, 2.0) if cand["cause"] == "stiffer-region" else min(r, 0.5)
    return param.z_of(cand["centroid"], radius, ratio)


def _described(fitter: Fitter, config: FitConfig, data: FrameData, Q, z, maxiter: int) -> list:
    """The kept balls with standard errors from the misfit's curvature (scaled by the residuals'
    scatter) and the discretisation (a refit on the model's coarser sibling), and whether radius
    and ratio are identified (:mod:`refine.correspond.region_errors`)."""
    from refine.correspond import region_errors as E

    model, param = fitter.model, fitter.param
    H, misfit = E.curvature(fitter, data, Q, z)
    cov, scatter = E.statistical_covariance(H, misfit, float(np.sum(data.w_boundary)))
    dz, factor = E.discretisation_change(model, model.coarser(), config, data, Q, z, param.n_balls, maxiter)
    nq = np.size(Q)
    return E.described(param, z, cov[nq:, nq:], dz, factor, H[nq:, nq:], scatter)
