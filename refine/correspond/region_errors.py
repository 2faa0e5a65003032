"""Honest standard errors of the refitted balls (:mod:`refine.correspond.region`), and which of
their numbers the data identify.

The misfit's curvature alone (twice the inverse Hessian: the misfit is about a chi-square) gave
standard errors 2-7x smaller than the centroids' actual errors and a radius and ratio that looked
measured where they were not: what limits a ball found from unlabelled clouds is mostly the
model's discretisation (a ball a cell or two across, its edge smeared over half a cell), not the
noise. Three parts are combined here, per unknown (centre, log radius, log ratio):

- the curvature's covariance ``2 H^-1`` (grips and balls together, central differences of the
  exact gradient), scaled by the residuals' observed scatter: the misfit at the fit over its
  expected value at pure noise (about one per boundary point), where that exceeds 1;
- the discretisation error: the same balls refitted, from the fit, on the model's coarser sibling
  (:meth:`refine.correspond.model.CloudModel.coarser`, about ``sqrt(2)`` coarser), the change
  divided by ``f - 1`` for the cells' size ratio ``f`` (Richardson's estimate at first order: a
  ball's cell indicator converges as the cell size, whatever the element's order); added in
  quadrature;
- identification: a radius or ratio whose total standard error on the log scale exceeds
  :data:`IDENTIFIED_LOG_SE` (known within less than a factor ``exp(0.5) = 1.65`` at one standard
  error) is reported as not identified, and so is the other where the two are traded off
  (correlation beyond :data:`TRADE_OFF`) (the value None, the fitted number kept as
  ``radius_fitted`` / ``relative_elasticity_fitted``), with the evidence: the correlation of log
  radius and log ratio in the curvature's covariance and the condition of their 2 x 2 Hessian
  block (a small stiff ball and a larger, less stiff one bend the boundary alike).
"""

from __future__ import annotations

from dataclasses import replace

import jax.numpy as jnp
import numpy as np

#: the largest total standard error of log radius or log ratio still called identified
IDENTIFIED_LOG_SE = 0.5
#: above this |correlation| of log radius and log ratio, one not identified makes the other not
#: identified either: a ratio run off towards a rigid ball leaves the radius at the value that
#: trades off with it, and the quadratic approximation behind the radius's error no longer holds
TRADE_OFF = 0.9


def curvature(fitter, data, Q, z, step: float = 1e-4) -> tuple[np.ndarray, float]:
    """The misfit's Hessian in all unknowns (grips ``Q`` flattened, then the balls' ``z``), by
    central differences of its exact gradient, symmetrised; and the misfit at ``(Q, z)``."""
    from refine.correspond.fit import _Objective

    if fitter.uses_shortlist:
        data = replace(data, candidates=fitter.shortlists(data, Q, z, fitter.model.start(None)))
    objective = _Objective(fitter, data, Q, z, fitter.model.start(None), True, 1.0)
    x = np.concatenate([np.ravel(Q), z])
    H = np.zeros((len(x), len(x)))
    for i in range(len(x)):
        e = np.zeros_like(x)
        e[i] = step * max(1.0, abs(x[i]))
        gp = np.asarray(objective.value_and_grad(jnp.asarray(x + e))[1])
        gm = np.asarray(objective.value_and_grad(jnp.asarray(x - e))[1])
        H[:, i] = (gp - gm) / (2 * e[i])
    value = float(objective.value_and_grad(jnp.asarray(x))[0])
    return 0.5 * (H + H.T), value


def statistical_covariance(H: np.ndarray, misfit: float, n_points: float) -> tuple[np.ndarray, float]:
    """``2 H^-1`` times the residuals' scatter factor ``max(1, misfit / n_points)``; NaN where H is
    singular. Returns ``(covariance, factor)``."""
    factor = max(1.0, misfit / max(n_points, 1.0))
    try:
        cov = 2.0 * np.linalg.inv(H)
    except np.linalg.LinAlgError:
        cov = np.full_like(H, np.nan)
    return factor * cov, factor


def coarse_data(data, fine, coarse):
    """``data`` for the coarser model: its seen boundary nodes (those within a fine cell of a node
    the fine model's nodes-to-cloud term pulled) and its tracked points located anew; no
    shortlists (the fit makes its own)."""
    from refine.correspond.geometry import seen_nodes

    out = replace(data, candidates=None)
    if data.node_weights is not None:
        seen = fine.mesh.nodes[fine.boundary_nodes][data.node_weights > 0]
        out = replace(out, node_weights=seen_nodes(coarse.mesh.nodes[coarse.boundary_nodes], seen,
                                                   fine.cell_size()).astype(float))
    if data.probe is not None:
        import jaxfem as jf

        X = np.einsum("pk,pkd->pd", data.probe[1], fine.mesh.nodes[data.probe[0]])
        p = jf.locate(coarse.mesh, X, tol=1e-3)
        out = replace(out, probe=(p.nodes, p.weights))
    return out


def discretisation_change(fine, coarse, config, data, Q, z, n_balls: int, maxiter: int):
    """The balls' unknowns refitted on ``coarse`` from the fine fit, minus the fine ones, and the
    cells' size ratio ``f``; ``(None, None)`` where there is no coarser model or its fit fails."""
    from refine.correspond.region import ball_fitter

    if coarse is None:
        return None, None
    fine_param = ball_fitter(fine, config, n_balls).param
    try:
        fitter = ball_fitter(coarse, config, n_balls)
        _, zc, _ = fitter.fit(coarse_data(data, fine, coarse), Q, _converted(z, fine_param, fitter.param), joint=True,
                              maxiter=maxiter)
    except Exception:  # noqa: BLE001 - a coarse mesh that cannot follow the motion gives no estimate
        return None, None
    return _converted(zc, fitter.param, fine_param) - np.asarray(z), coarse.cell_size() / fine.cell_size()


def _converted(z, source, target) -> np.ndarray:
    """Balls' unknowns of one :class:`SoftBalls` in another's units (centres scale by cell size)."""
    v = list(source.values(z).values())
    return target.z_of([b["centre"] for b in v], [b["radius"] for b in v], [b["ratio"] for b in v])


def described(param, z, cov_stat: np.ndarray, dz: np.ndarray | None, factor: float | None, H_balls: np.ndarray,
              scatter: float) -> list:
    """The kept balls as findings with total standard errors and identification (module
    docstring).

    Args:
        param: the :class:`refine.correspond.region.SoftBalls`; z its unknowns.
        cov_stat: ``(size, size)`` the balls' block of the scaled curvature covariance.
        dz: the coarse refit's change of z, or None (no discretisation estimate); factor the cells'
            size ratio.
        H_balls: the balls' block of the Hessian (for the radius-ratio condition).
        scatter: the residuals' scatter factor applied.
    """
    dim, k = param.dim, param.dim + 2
    var_stat = np.diag(cov_stat)
    var_disc = np.zeros(len(z)) if dz is None else (np.asarray(dz) / (factor - 1.0)) ** 2
    se = np.sqrt(np.where(var_stat >= 0, var_stat, np.nan) + var_disc)
    out = []
    for b, q in enumerate(np.reshape(z, (param.n_balls, k))):
        i = b * k
        s, s_stat = se[i: i + k], np.sqrt(np.abs(var_stat[i: i + k]))
        rr = cov_stat[i + dim: i + k, i + dim: i + k]
        corr = float(rr[0, 1] / np.sqrt(rr[0, 0] * rr[1, 1])) if np.all(np.diag(rr) > 0) else float("nan")
        Hb = H_balls[i + dim: i + k, i + dim: i + k]
        d = np.sqrt(np.abs(np.diag(Hb))) + 1e-300
        cond = float(np.linalg.cond(Hb / np.outer(d, d)))
        ratio, radius = float(np.exp(q[dim + 1])), float(np.exp(q[dim]))
        ok_r, ok_k = bool(s[dim] <= IDENTIFIED_LOG_SE), bool(s[dim + 1] <= IDENTIFIED_LOG_SE)
        if not (ok_r and ok_k) and not abs(corr) <= TRADE_OFF:  # one undetermined drags the other along
            ok_r = ok_k = False
        row = {"cause": "stiffer-region" if ratio > 1 else "softer-region",
               "centroid": (q[:dim] * param.scale).tolist(), "centroid_se": (s[:dim] * param.scale).tolist(),
               "radius": radius if ok_r else None, "radius_se": radius * float(s[dim]),
               "relative_elasticity": ratio if ok_k else None, "relative_elasticity_se": ratio * float(s[dim + 1]),
               "radius_fitted": radius, "relative_elasticity_fitted": ratio,
               "identified": {"radius": ok_r, "relative_elasticity": ok_k},
               "log_se": {"radius": float(s[dim]), "relative_elasticity": float(s[dim + 1])},
               "se_parts": {"curvature": (s_stat * np.r_[[param.scale] * dim, 1.0, 1.0]).tolist(),
                            "discretisation": None if dz is None else
                            (np.abs(dz[i: i + k]) / (factor - 1.0) * np.r_[[param.scale] * dim, 1.0, 1.0]).tolist(),
                            "scatter_factor": scatter, "coarse_factor": factor,
                            "units": "centre: length; radius and ratio: log scale"},
               "trade_off": {"log_radius_log_ratio_correlation": corr, "condition": cond}}
        if not (ok_r and ok_k):
            row["note"] = (f"radius and ratio not both identified: log-scale standard errors "
                           f"{s[dim]:.2g} and {s[dim + 1]:.2g} (limit {IDENTIFIED_LOG_SE}), their correlation "
                           f"{corr:.3f}, condition {cond:.3g}: a smaller, stiffer ball bends the boundary alike")
        out.append(row)
    return out
