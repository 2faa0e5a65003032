"""Levenberg-Marquardt with exact Jacobians on a :class:`~refine.model.Compiled` model."""

from __future__ import annotations

import time

import numpy as np

from refine.model.parametrize import infeasibility
from refine.optimize.result import RefineResult


def levenberg_marquardt(compiled: Compiled, points, sigma: float, z0=None, max_steps: int = 30,
                        rtol: float = 1e-6, chi2_tol: float = 0.05) -> RefineResult:
    """Levenberg-Marquardt with exact Jacobians on ``compiled`` (see :class:`Compiled`), matching
    the ``points`` mask. The same algorithm as :func:`least_squares` with the compiled pieces
    reused across calls. Every evaluation (a step tried) is a forward solve with its Jacobian
    (:meth:`Compiled.evaluate`), so a rejected step costs one evaluation and an accepted one needs
    no other; a step the parametrisation calls infeasible (:func:`refine.model.parametrize.infeasibility`:
    a squashed cell, a hole over a tracked point) is rejected without a solve.

    It stops when a step lowers chi^2 (the sum of squared noise-weighted residuals) by less than
    ``rtol`` of it or by less than ``chi2_tol``. A change of 0.05 in chi^2 is far below what a
    model comparison sees (margins of 10) and about what moving a parameter by a fifth of its
    standard error costs (0.2^2); a wrong hypothesis with a large misfit otherwise crept on for
    all ``max_steps`` at ~0.1 per step."""
    obs = compiled.model.obs
    meas = obs.displacements[:, points]
    valid = np.isfinite(meas).all(-1)
    meas = np.nan_to_num(meas)
    z = np.asarray(compiled.param.z0 if z0 is None else z0, float)

    def resid(pred):
        return ((pred[:, points] - meas) / sigma)[valid].reshape(-1)

    t0 = time.perf_counter()
    pred = compiled.predict(z)
    r = resid(pred)
    cost = float(r @ r)
    if not np.isfinite(cost):  # the start does not solve: no step can be judged against it
        return RefineResult(values={"z": z, **compiled.param.values(z)}, error=np.inf, n_forward=1, n_gradient=1,
                            seconds=time.perf_counter() - t0, history=[], method="levenberg-marquardt",
                            converged=False, message="the model does not solve at the start")
    lam, history, n_fwd, n_infeasible, ok = 1e-3, [], 1, 0, False
    for step in range(max_steps):
        J = compiled.jacobian(z)[:, points][valid].reshape(len(r), -1) / sigma  # came with the solve at z
        g, H = J.T @ r, J.T @ J
        while True:
            dz = -np.linalg.solve(H + lam * np.diag(np.diag(H) + 1e-12), g)
            if infeasibility(compiled.param, z + dz):
                new, n_infeasible = np.inf, n_infeasible + 1
            else:
                pred_new = compiled.predict(z + dz)
                n_fwd += 1
                r_new = resid(pred_new)
                new = float(r_new @ r_new) if np.all(np.isfinite(r_new)) else np.inf
            if new < cost:
                break
            lam *= 10.0
            if lam > 1e8:
                break
        history.append({"step": step + 1, "misfit": 0.5 * min(new, cost), "lambda": lam, "z": (z + dz).tolist(),
                        "infeasible": n_infeasible})
        if new >= cost:
            ok = True  # no descent possible: at a minimum up to round-off
            break
        gain = cost - new
        z, r, cost, lam = z + dz, r_new, new, max(lam / 10.0, 1e-9)
        if gain < max(rtol * (cost + gain), chi2_tol) or np.max(np.abs(dz)) < 1e-8:
            ok = True
            break
    return RefineResult(values={"z": z, **compiled.param.values(z)}, error=0.5 * cost,
                        n_forward=n_fwd, n_gradient=n_fwd, seconds=time.perf_counter() - t0,
                        history=history, method="levenberg-marquardt", converged=ok,
                        message="converged" if ok else f"stopped after {max_steps} steps")
