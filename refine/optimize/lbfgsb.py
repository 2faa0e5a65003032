"""Bounded L-BFGS (SciPy) with adjoint gradients, for fields of many unknowns."""

from __future__ import annotations

import time

import jax.numpy as jnp
import numpy as np

from refine.optimize.result import RefineResult


def lbfgsb(objective: Objective, z0=None, bounds=None, maxiter: int = 100, tol: float = 1e-5,
           progress: bool = False) -> RefineResult:
    """Bounded L-BFGS (SciPy's L-BFGS-B) on the objective value with adjoint gradients.

    Suited to many unknowns (a modulus per cell): one gradient costs one adjoint solve per frame.
    ``bounds`` is ``(lower, upper)`` on z (log-moduli), e.g. ``(-5, 5)``; ``tol`` bounds the
    largest component of the projected gradient at convergence. The value and its gradient are
    compiled once per objective; the quasi-Newton iteration itself runs in SciPy (jaxopt's
    compiled loop put the solve into its line search several times over and took a minute to
    compile, and jaxopt is no longer maintained). ``progress`` shows a tqdm bar of iterations.
    """
    import scipy.optimize

    z = np.asarray(objective.param.z0 if z0 is None else z0, float)
    lo, hi = (-np.inf, np.inf) if bounds is None else bounds
    value_and_grad = objective.value_and_grad  # compiled once per objective, so later fits are warm

    last = {}

    def fun(zz):
        objective.n_forward += 1
        objective.n_gradient += 1
        v, g = value_and_grad(jnp.asarray(zz))
        v, g = float(v), np.asarray(g, float)
        last.update(x=np.array(zz), g=g)
        return (v, g) if np.isfinite(v) else (np.inf, np.zeros_like(zz))

    history = []
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=maxiter, desc="L-BFGS-B", unit="it")

    def callback(intermediate_result):
        x = intermediate_result.x
        # the accepted iterate is the line search's last evaluation: its gradient is at hand
        pg = np.abs(np.clip(x - last["g"], lo, hi) - x).max() if np.array_equal(last["x"], x) else np.nan
        row = {"step": len(history) + 1, "value": float(intermediate_result.fun), "error": float(pg)}
        if x.size <= 16:  # a few unknowns: keep the iterates, as least_squares() does
            row["z"] = x.tolist()
        history.append(row)
        if bar is not None:
            bar.update(1)
            bar.set_postfix(value=row["value"])

    n0, g0 = objective.n_forward, objective.n_gradient  # count this run only
    t0 = time.perf_counter()
    res = scipy.optimize.minimize(fun, z, jac=True, method="L-BFGS-B", bounds=[(lo, hi)] * z.size,
                                  callback=callback, options={"maxiter": maxiter, "gtol": tol})
    if bar is not None:
        bar.close()
    return RefineResult(values={"z": res.x, **objective.param.values(res.x)}, error=float(res.fun),
                        n_forward=objective.n_forward - n0, n_gradient=objective.n_gradient - g0,
                        seconds=time.perf_counter() - t0, history=history, method="l-bfgs-b",
                        converged=bool(res.success), message=str(res.message))
