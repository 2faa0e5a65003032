"""Levenberg-Marquardt (and Gauss-Newton, the same loop undamped) with exact Jacobians: the one
loop behind :func:`levenberg_marquardt` (a :class:`~refine.model.Compiled` model at a point mask)
and :func:`~refine.optimize.least_squares` (an :class:`~refine.model.Objective`)."""

from __future__ import annotations

import time
from typing import Callable

import numpy as np
from jaxtyping import Float

from refine.measures import Residuals
from refine.model.parametrize import infeasibility
from refine.optimize.result import RefineResult

Vector = Float[np.ndarray, "k"]


def levenberg_marquardt(compiled: Compiled, points, sigma: float, z0=None, max_steps: int = 30,
                        rtol: float = 1e-6, chi2_tol: float = 0.05) -> RefineResult:
    """Levenberg-Marquardt with exact Jacobians on ``compiled`` (see :class:`Compiled`), matching
    the ``points`` mask with noise ``sigma``. The compiled pieces are reused across calls. Every
    evaluation (a step tried) is a forward solve with its Jacobian (:meth:`Compiled.evaluate`), so
    a rejected step costs one evaluation and an accepted one needs no other; a step the
    parametrisation calls infeasible (:func:`refine.model.parametrize.infeasibility`: a squashed
    cell, a hole over a tracked point) is rejected without a solve. Stops as :func:`minimise`
    says (``chi2_tol`` 0.05: far below the margins a model comparison sees, about a fifth of a
    standard error; a wrong hypothesis otherwise creeps on for all ``max_steps``)."""
    at = Residuals.at(compiled.model.obs.displacements, points, sigma)
    z = np.asarray(compiled.param.z0 if z0 is None else z0, float)
    return minimise(lambda zz: at(compiled.predict(zz)), lambda zz: at.jacobian(compiled.jacobian(zz)),
                    compiled.param, z, max_steps=max_steps, rtol=rtol, chi2_tol=chi2_tol)


def minimise(residuals: Callable[[Vector], Float[np.ndarray, "n"]],
             jacobian: Callable[[Vector], Float[np.ndarray, "n k"]], param, z: Vector, *, max_steps: int = 30,
             rtol: float = 1e-6, chi2_tol: float = 0.05, xtol: float = 1e-8, damped: bool = True,
             on_evaluation: Callable[[Vector, float], None] | None = None,
             method: str = "levenberg-marquardt") -> RefineResult:
    """The least-squares loop: minimise chi^2 = |r(z)|^2 from ``z``.

    Levenberg-Marquardt (``damped``): steps solve ``(H + lambda diag(H)) dz = -g`` with
    ``H = J^T J``, ``g = J^T r``; a step that does not lower chi^2 is retried with ten times the
    damping, an accepted one divides it by ten. Gauss-Newton (not ``damped``): ``lambda = 0``, and
    a step that does not lower chi^2 ends the fit. ``jacobian(z)`` is only asked for at accepted
    points (a caller whose evaluations bring the Jacobian along caches it). Steps that ``param``
    calls infeasible are rejected without an evaluation.

    Stops when a step lowers chi^2 by less than ``rtol`` of it or by less than ``chi2_tol``,
    moves no unknown by more than ``xtol``, or no step lowers it. ``on_evaluation(z, chi2)`` is
    told of every evaluation. ``error`` is chi^2 / 2; ``history`` has one row per step.
    """
    t0 = time.perf_counter()

    def evaluate(zz):
        rr = residuals(zz)
        cc = float(rr @ rr) if np.all(np.isfinite(rr)) else np.inf
        if on_evaluation is not None:
            on_evaluation(zz, cc)
        return rr, cc

    r, cost = evaluate(z)
    cost = float(r @ r)
    if not np.isfinite(cost):  # the start does not solve: no step can be judged against it
        return RefineResult(values={"z": z, **param.values(z)}, error=np.inf, n_forward=1, n_gradient=1,
                            seconds=time.perf_counter() - t0, history=[], method=method,
                            converged=False, message="the model does not solve at the start")
    lam, history, n_fwd, n_infeasible, ok = (1e-3 if damped else 0.0), [], 1, 0, False
    for step in range(max_steps):
        J = jacobian(z)
        g, H = J.T @ r, J.T @ J
        while True:
            A = H + lam * np.diag(np.diag(H) + 1e-12)
            dz = -np.linalg.solve(A, g)
            if infeasibility(param, z + dz) and hasattr(param, "constraints"):
                dz = constrained_step(param.constraints, z, dz, A, g)  # onto the constraints, not rejected whole
            if infeasibility(param, z + dz):
                new, n_infeasible = np.inf, n_infeasible + 1
            else:
                r_new, new = evaluate(z + dz)
                n_fwd += 1
            if new < cost or not damped:
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
        z, r, cost, lam = z + dz, r_new, new, (max(lam / 10.0, 1e-9) if damped else 0.0)
        if gain < max(rtol * (cost + gain), chi2_tol) or np.max(np.abs(dz)) < xtol:
            ok = True
            break
    return RefineResult(values={"z": z, **param.values(z)}, error=0.5 * cost,
                        n_forward=n_fwd, n_gradient=n_fwd, seconds=time.perf_counter() - t0,
                        history=history, method=method, converged=ok,
                        message="converged" if ok else f"stopped after {max_steps} steps")


_MARGIN = 1e-9  # how far inside its constraints a slid step ends (their units: mm for a hole's gaps)


def constrained_step(constraints: Callable[[Vector], np.ndarray], z: Vector, dz: Vector, A, g) -> Vector:
    """The step's quadratic model ``g.d + d.A.d / 2`` minimised where ``constraints(z + d) >= 0``
    (SLSQP from ``d = 0``; a parametrisation's cheap checks without a solve, e.g. a hole kept off
    every tracked point): a step that runs into a constraint slides along it instead of being
    rejected whole and retried ever more damped (a hole fit can stall so against one tracked point,
    its modulus left at the start). ``dz`` where SLSQP fails."""
    from scipy import optimize

    r = optimize.minimize(lambda d: g @ d + 0.5 * d @ A @ d, np.zeros_like(dz), jac=lambda d: g + A @ d,
                          constraints=[{"type": "ineq", "fun": lambda d: constraints(z + d) - _MARGIN}],
                          method="SLSQP", options={"maxiter": 100, "ftol": 1e-12})
    # the caller checks it again: SLSQP ends on its constraints up to round-off (-6e-8 seen), so they
    # are asked with a margin; without it SciPy 1.17's SLSQP ends a hair outside, every step is
    # rejected, and the fit stops short of the constrained minimum (4e-5 on the toy wall)
    return np.asarray(r.x, float) if r.success else dz

