"""Tensor least squares: steps that minimise a higher-order Taylor model of the residuals.

The derivative tensors of an :class:`~refine.model.Objective`'s residuals come from nested forward
mode through the implicit equilibrium, all from one forward solve per iterate.
"""

from __future__ import annotations

import time

import jax
import jax.numpy as jnp
import numpy as np

from refine.exceptions import FitError
from refine.optimize.result import RefineResult


def _taylor_function(objective, order: int):
    """Compiled ``z -> [r, J, H, ...]``: the residuals and their derivative tensors up to
    ``order`` (``(m,)``, ``(m, k)``, ``(m, k, k)``, ...), all from one forward solve per frame.

    Nested forward mode through the implicit equilibrium: the nonlinear solve runs once, at the
    bottom, and every derivative above it is a linear solve with the tangent matrix at the
    converged state (the factorisation is reused), so a third-order model costs k + k^2 + k^3
    back-substitutions per frame, not forward solves."""
    key = f"_taylor_fn{order}"
    fn = objective.__dict__.get(key)
    if fn is None:
        def g(z):
            return objective.residuals(z), ()

        for _ in range(order):
            def g(z, prev=g):
                def top(zz):
                    hi, lower = prev(zz)
                    return hi, (hi,) + lower

                return jax.jacfwd(top, has_aux=True)(z)

        def all_orders(z):
            top, lower = g(z)
            return list(lower[::-1]) + [top]

        fn = jax.jit(all_orders)
        objective.__dict__[key] = fn
    return fn


def _model(ders, d):
    """Taylor model of the residuals at the step ``d`` and its Jacobian in ``d``."""
    r, J = ders[0], ders[1]
    m, Jm = r + J @ d, J.copy()
    fact = 1.0
    for k, T in enumerate(ders[2:], start=2):
        fact *= k
        Tk1 = T
        for _ in range(k - 1):  # contract all but the last index with d
            Tk1 = Tk1 @ d
        m = m + (Tk1 @ d) / fact
        Jm = Jm + k * Tk1 / fact  # symmetric tensor: d/dd of T[d,...,d] is k T[d,...,d,.]
    return m, Jm


def _minimise_model(ders, radius: float, iters: int = 60):
    """Minimiser of |model(d)|^2 with |d|_inf <= radius, by Levenberg-Marquardt on the polynomial
    (no forward solves: the model is a few small tensors)."""
    k = ders[1].shape[1]
    d = np.zeros(k)
    m, Jm = _model(ders, d)
    cost, lam = float(m @ m), 1e-8
    for _ in range(iters):
        A, g = Jm.T @ Jm, Jm.T @ m
        step = -np.linalg.solve(A + lam * np.diag(np.diag(A) + 1e-300), g)
        trial = d + step
        s = np.max(np.abs(trial))
        if s > radius:  # pull back onto the trust region
            trial = trial * (radius / s)
        m_new, J_new = _model(ders, trial)
        new = float(m_new @ m_new)
        if new < cost:
            moved = np.max(np.abs(trial - d))
            d, m, Jm, cost, lam = trial, m_new, J_new, new, max(lam / 10.0, 1e-12)
            if moved < 1e-12:
                break
        else:
            lam *= 10.0
            if lam > 1e10:
                break
    return d, 0.5 * cost


def tensor_least_squares(objective, z0=None, order: int = 3, rtol: float = 1e-6, xtol: float = 1e-7,
                         max_steps: int = 30, radius: float = 3.0, progress: bool = False) -> RefineResult:
    """Least squares by a tensor method: each step minimises an ``order``-th order Taylor model of
    the residuals (Gauss-Newton is ``order=1``) within a trust region, so each forward solve buys
    more than a linear model can give.

    The exact derivative tensors come from nested implicit differentiation at the converged
    state (:func:`_taylor_function`): one forward solve and ``k + k^2 + ...`` linear solves with
    the same factorisation per evaluation. For a handful of unknowns (``k^order`` grows fast:
    at most 6 unknowns at order 3). A step that does not lower the misfit is rejected and the
    trust region (``radius``, in the units of z: log-moduli) shrinks. ``n_forward`` counts forward
    solves over all frames, ``n_gradient`` the derivative evaluations (both one per iterate).
    """
    z = np.asarray(objective.param.z0 if z0 is None else z0, float)
    if z.size ** order > 216:
        raise FitError(f"tensor_least_squares: {z.size} unknowns at order {order} need {z.size ** order} "
                         "tangent solves per evaluation; use least_squares() or a lower order")
    if not (isinstance(objective.param.regularization(z), float) and objective.param.regularization(z) == 0.0):
        raise FitError("tensor_least_squares() fits unregularised parametrisations; use lbfgsb() for a field")
    fn = _taylor_function(objective, order)
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(desc=f"tensor least squares (order {order})", unit="solve")
    history, n_eval = [], 0
    t0 = time.perf_counter()

    def evaluate(zz):
        nonlocal n_eval
        n_eval += 1
        ders = [np.asarray(a, float) for a in fn(jnp.asarray(zz))]
        m = ders[0].shape[0]
        ders = [ders[0]] + [a.reshape(m, *([zz.size] * i)) for i, a in enumerate(ders[1:], start=1)]
        ok = all(np.all(np.isfinite(a)) for a in ders)
        misfit = 0.5 * float(ders[0] @ ders[0]) if ok else np.inf
        history.append({"step": len(history), "z": zz.tolist(), "misfit": misfit})
        if bar is not None:
            bar.update(1)
            bar.set_postfix(misfit=misfit)
        return ders, misfit

    ders, misfit = evaluate(z)
    if not np.isfinite(misfit):
        raise FitError(f"tensor_least_squares: the model cannot be solved at the start z0 = {z.tolist()}")
    ok, message = False, f"stopped after {max_steps} steps"
    for _ in range(max_steps):
        d, predicted = _minimise_model(ders, radius)
        if np.max(np.abs(d)) < xtol or misfit - predicted <= rtol * max(misfit, 1e-300) * 1e-3:
            ok, message = True, "converged"
            break
        trial = z + d
        new_ders, new = evaluate(trial)
        if new < misfit:
            rel = (misfit - new) / max(misfit, 1e-300)
            z, ders, misfit = trial, new_ders, new
            radius = max(radius, 2.0 * float(np.max(np.abs(d))))
            if rel < rtol or np.max(np.abs(d)) < xtol:
                ok, message = True, "converged"
                break
        else:
            radius = 0.25 * float(np.max(np.abs(d)))
            if radius < xtol:
                ok, message = True, "converged (no descent left)"
                break
    if bar is not None:
        bar.close()
    objective.n_forward += n_eval
    objective.n_gradient += n_eval
    return RefineResult(values={"z": z, **objective.param.values(z)}, error=misfit, n_forward=n_eval,
                        n_gradient=n_eval, seconds=time.perf_counter() - t0, history=history,
                        method=f"tensor-least-squares-{order}", converged=ok, message=message)
