"""Gauss-Newton and Levenberg-Marquardt (optimistix) on an :class:`~refine.model.Objective`."""

from __future__ import annotations

import time

import jax
import jax.numpy as jnp
import numpy as np

from refine.optimize.result import RefineResult


def least_squares(objective: Objective, z0=None, method: str = "lm", rtol: float = 1e-6, atol: float = 1e-8,
                  max_steps: int = 50, progress: bool = False) -> RefineResult:
    """Gauss-Newton (``"gn"``) or Levenberg-Marquardt (``"lm"``) with exact Jacobians (optimistix).

    Suited to a few unknowns (regions, geometry): each Jacobian costs one tangent solve per
    unknown and frame, reusing the converged state. The residuals are compared component-wise in
    noise units, so ``atol`` is the change of a residual (in standard deviations) that counts as
    no change: 1e-8 asks for far more than the data can tell; 1e-4 is plenty. ``progress`` shows a
    tqdm bar of evaluations (one forward solve over all frames and one Jacobian each).
    """
    import optimistix as optx

    z0 = objective.param.z0 if z0 is None else jnp.asarray(z0, float)
    history = []
    reg = objective.param.regularization
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(desc=f"least squares ({method})", unit="solve")

    def record(zz, rr):
        history.append({"step": len(history), "z": np.asarray(zz).tolist(),
                        "misfit": float(0.5 * np.sum(np.asarray(rr) ** 2))})
        if bar is not None:
            bar.update(1)
            bar.set_postfix(misfit=history[-1]["misfit"])

    if not (isinstance(reg(z0), float) and reg(z0) == 0.0):
        raise ValueError("least_squares() fits unregularised parametrisations; use lbfgsb() for a "
                         "regularised field")
    solver = {"lm": optx.LevenbergMarquardt, "gn": optx.GaussNewton}[method](rtol=rtol, atol=atol)
    n0 = objective.n_forward  # the objective may have been used before: count this run only
    objective._recorder = record
    t0 = time.perf_counter()
    sol = optx.least_squares(_residual_function(objective), solver, z0, max_steps=max_steps, throw=False)
    if bar is not None:
        bar.close()
    z = np.asarray(sol.value)
    ok = bool(sol.result == optx.RESULTS.successful)
    n_jac = int(sol.stats.get("num_steps", 0))
    at_z = [h["misfit"] for h in history if np.array_equal(h["z"], z.tolist())]
    error = at_z[-1] if at_z else float(objective.value(z))  # no extra solve when the end point was seen
    return RefineResult(values={"z": z, **objective.param.values(z)}, error=error,
                        n_forward=objective.n_forward - n0, n_gradient=n_jac, seconds=time.perf_counter() - t0,
                        history=history, method=f"least-squares-{method}", converged=ok,
                        message=str(optx.RESULTS[sol.result]) if not ok else "converged")


def _residual_function(objective: Objective):
    """The residual function handed to optimistix, made once per objective: optimistix compiles
    per function object, and the compilation (the whole nonlinear solve and its tangent, tens of
    seconds) is then reused by every later fit of the same objective."""
    fn = objective.__dict__.get("_residual_fn")
    if fn is None:
        def fn(z, _):
            objective._count("forward")
            r = objective.residuals(z)
            jax.debug.callback(lambda zz, rr: objective._recorder(zz, rr), z, r)  # looked up per run
            return r

        objective._residual_fn = fn
    return fn
