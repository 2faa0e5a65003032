"""Levenberg-Marquardt and Gauss-Newton on an :class:`~refine.model.Objective` (the loop of
:mod:`refine.optimize.levenberg_marquardt`)."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from refine.exceptions import SearchError
from refine.optimize.levenberg_marquardt import minimise
from refine.optimize.result import RefineResult

METHODS = {"lm": "least-squares-lm", "gn": "least-squares-gn"}


def least_squares(objective: Objective, z0=None, method: str = "lm", rtol: float = 1e-6, atol: float = 1e-8,
                  max_steps: int = 50, progress: bool = False) -> RefineResult:
    """Levenberg-Marquardt (``"lm"``) or Gauss-Newton (``"gn"``: the same loop, undamped) with
    exact Jacobians, by :func:`~refine.optimize.levenberg_marquardt.minimise`.

    Suited to a few unknowns (regions, geometry): each evaluation is one forward solve and its
    Jacobian (one tangent solve per unknown and frame at the converged state), compiled once per
    objective (:attr:`Objective.residuals_and_jacobian`). It stops when a step lowers chi^2 (the
    sum of squared noise-weighted residuals) by less than ``rtol`` of it or by less than
    ``atol``, or moves no unknown by more than ``atol``. ``history`` has one row per evaluation
    (``z``, ``misfit`` = chi^2 / 2); ``progress`` shows a tqdm bar of them.
    """
    if method not in METHODS:
        raise SearchError(f"least_squares() method must be one of {sorted(METHODS)}, not {method!r}")
    z = np.asarray(objective.param.z0 if z0 is None else z0, float)
    reg = objective.param.regularization(jnp.asarray(z))
    if not (isinstance(reg, float) and reg == 0.0):
        raise SearchError("least_squares() fits unregularised parametrisations; use lbfgsb() for a "
                          "regularised field")
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(desc=f"least squares ({method})", unit="solve")
    history, last = [], {}

    def residuals(zz):
        J, r = objective.residuals_and_jacobian(jnp.asarray(zz))
        last.update(z=np.array(zz), J=np.asarray(J))
        objective.n_forward += 1
        objective.n_gradient += 1
        return np.asarray(r)

    def jacobian(zz):  # came with the evaluation at zz (the loop asks at accepted points only)
        if not np.array_equal(last["z"], zz):
            residuals(zz)
        return last["J"]

    def record(zz, chi2):
        history.append({"step": len(history), "z": np.asarray(zz).tolist(), "misfit": 0.5 * chi2})
        if bar is not None:
            bar.update(1)
            bar.set_postfix(misfit=history[-1]["misfit"])

    r = minimise(residuals, jacobian, objective.param, z, max_steps=max_steps, rtol=rtol, chi2_tol=atol,
                 xtol=atol, damped=method == "lm", on_evaluation=record, method=METHODS[method])
    if bar is not None:
        bar.close()
    return RefineResult(values=r.values, error=r.error, n_forward=r.n_forward, n_gradient=r.n_gradient,
                        seconds=r.seconds, history=history, method=r.method, converged=r.converged,
                        message=r.message)
