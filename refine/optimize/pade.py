"""One unknown in few forward solves: Pade steps on the equilibrium's Taylor series.

From one forward solve at the current value, :func:`jaxfem.series.equilibrium_series` gives the
Taylor series of every frame's equilibrium in the unknown (the asymptotic-numerical method: one
factorisation, then one back-substitution per order), and so the series of the guide-point
residuals, ``r(t) = sum_k C_k t^k``. That series converges only up to the nearest singularity
of the equilibrium in the complex plane: for a region's modulus, a pole at a negative modulus, so
from the uniform model (ratio 1) it reaches ratios up to about 3, and a truncated Taylor model of
any order cannot step to a region ten times stiffer. A vector Pade approximant, one shared
denominator, ``r(t) ~ N(t) / Q(t)``, continues it past that radius (it reproduces the pole
instead of fighting it); its minimiser of ``|r(t)|^2`` is the step.

On the paper's case one Pade step of order 16 from the uniform model lands near the
least-squares minimiser (benchmarks/brent_vs_gradient.py measures it). Each iterate costs one
forward solve and one series (counted as one derivative evaluation, as the tensor method's
derivative tensors are).
"""

from __future__ import annotations

import time

import jax.numpy as jnp
import numpy as np
from jax.experimental import jet
from scipy.optimize import minimize_scalar

from jaxfem.series import equilibrium_series

from refine.model.parametrize import RegionModuli
from refine.exceptions import FitError
from refine.optimize.result import RefineResult


class VectorPade:
    """Vector Pade approximant ``[L/M]`` of the series ``sum_k C[k] t^k`` (``C (>= L+M+1, m)``):
    ``N(t) / Q(t)`` with ``Q(0) = 1`` shared by every component, chosen so that the coefficients
    ``L+1 .. L+M`` of ``Q(t) sum_k C[k] t^k`` vanish in least squares over the components.

    Attributes:
        numerator: ``(L+1, m)``; denominator: ``(M+1,)``, in the variable ``t``.
    """

    def __init__(self, C, L: int, M: int):
        C = np.asarray(C, float)
        if C.ndim != 2 or len(C) < L + M + 1:
            raise FitError(f"VectorPade: [{L}/{M}] needs {L + M + 1} coefficients, got {len(C)}")
        # balance the powers of t (the approximant does not depend on the scale of t; the least
        # squares' conditioning does): coefficients at t = tau s decay like 1 in s
        norms = np.linalg.norm(C, axis=1)
        nz = np.flatnonzero(norms[1:] > 0) + 1
        tau = (norms[nz[0]] / norms[nz[-1]]) ** (1.0 / max(nz[-1] - nz[0], 1)) if len(nz) > 1 else 1.0
        tau = 1.0 / tau if np.isfinite(tau) and tau > 0 else 1.0
        S = C[: L + M + 1] * (tau ** np.arange(L + M + 1))[:, None]
        m = C.shape[1]
        A, b = np.zeros((M * m, M)), np.zeros(M * m)
        for i, j in enumerate(range(L + 1, L + M + 1)):
            rows = slice(i * m, (i + 1) * m)
            b[rows] = -S[j]
            for q in range(1, M + 1):
                if j - q >= 0:
                    A[rows, q - 1] = S[j - q]
        q = np.r_[1.0, np.linalg.lstsq(A, b, rcond=None)[0]] if M else np.ones(1)
        num = np.array([sum(q[i] * S[j - i] for i in range(min(j, M) + 1)) for j in range(L + 1)])
        self.numerator = num / (tau ** np.arange(L + 1))[:, None]
        self.denominator = q / tau ** np.arange(M + 1)

    def __call__(self, t):
        t = np.asarray(t, float)
        powers_n = t[..., None] ** np.arange(len(self.numerator))
        powers_q = t[..., None] ** np.arange(len(self.denominator))
        return (powers_n @ self.numerator) / (powers_q @ self.denominator)[..., None]

    def pole_free(self, lo: float, hi: float) -> tuple[float, float]:
        """The largest interval around 0 within ``[lo, hi]`` where the denominator has no root."""
        roots = np.roots(self.denominator[::-1]) if len(self.denominator) > 1 else np.array([])
        real = roots[np.abs(roots.imag) <= 1e-9 * np.maximum(1.0, np.abs(roots))].real
        left = max([lo] + [r for r in real if r < 0])
        right = min([hi] + [r for r in real if r > 0])
        return left, right


def pade_minimiser(C, L: int, M: int, lo: float, hi: float, grid: int = 4001) -> tuple[float, float]:
    """The ``t`` in ``[lo, hi]`` (pole-free around 0) that minimises ``|N(t)/Q(t)|^2`` of the
    ``[L/M]`` approximant, and that minimum (half of it: the misfit's scale)."""
    f = VectorPade(C, L, M)
    a, b = f.pole_free(lo, hi)
    margin = 1e-6 * (b - a)
    ts = np.linspace(a + margin, b - margin, grid)
    vals = np.sum(f(ts) ** 2, axis=-1)
    k = int(np.nanargmin(vals))
    o = minimize_scalar(lambda t: float(np.sum(f(t) ** 2)), bounds=(ts[max(k - 1, 0)], ts[min(k + 1, grid - 1)]),
                        method="bounded", options={"xatol": 1e-12 * max(1.0, abs(ts[k]))})
    t = float(o.x) if o.fun <= vals[k] else float(ts[k])
    return t, 0.5 * float(np.sum(f(t) ** 2))


def _variable(param, variable: str | None) -> str:
    if variable is None:
        variable = "exp" if isinstance(param, RegionModuli) else "z"
    if variable not in ("exp", "z"):
        raise FitError(f"variable must be 'exp' (the ratio exp(z) of a log-space modulus) or 'z', not {variable!r}")
    return variable


def _path(objective, z0: float, variable: str, order: int):
    """The parameters along the unknown, ``theta(t)``, as Taylor coefficients of orders 1..order
    of every entry that moves (``z = log(exp(z0) + t)`` or ``z = z0 + t``)."""
    theta, param = objective.theta, objective.param
    s0 = float(np.exp(z0))

    def along(t):
        z = jnp.log(s0 + t) if variable == "exp" else z0 + t
        return param.apply(theta, jnp.reshape(z, (1,)))

    base = along(0.0)
    other = along(0.1 * (s0 if variable == "exp" else 1.0))
    # the moving entries (equilibrium_series refuses prescribed displacements and loads)
    keys = [k for k in base if not np.array_equal(np.asarray(base[k]), np.asarray(other[k]))]
    terms = [1.0] + [0.0] * (order - 1)
    terms = [jnp.asarray(c) for c in terms]
    _, series = jet.jet(lambda t: [along(t)[k] for k in keys], (jnp.asarray(0.0),), (terms,), factorial_scaled=False)
    return base, {k: jnp.stack([jnp.asarray(series[i][j]) for j in range(order)]) for i, k in enumerate(keys)}


def pade_least_squares(objective, z0=None, order: int = 16, degree: int | None = None, bounds=None,
                       variable: str | None = None, xtol: float = 1e-7, max_steps: int = 10,
                       progress: bool = False) -> RefineResult:
    """Least squares in one unknown by Pade steps on the equilibrium's Taylor series.

    Each iterate: one forward solve at ``z``, the Taylor series of every frame's equilibrium to
    ``order`` in the unknown (:func:`jaxfem.series.equilibrium_series`), the guide residuals'
    vector series, its ``[degree/degree]`` Pade approximant (default ``order // 2``) and the
    minimiser of its squared norm, pole-free and within ``bounds``, as the next ``z``. A step
    that does not lower the misfit (seen at the next solve) is halved.

    Args:
        objective: an :class:`~refine.model.Objective` with a one-unknown, unregularised
            parametrisation.
        z0: start (default the parametrisation's).
        order: Taylor order of the series (2 x degree at least).
        bounds: ``(lo, hi)`` on z (default: a factor 30 either way for a modulus ratio, +-3 else).
        variable: the series' variable: ``"exp"`` (the modulus ratio exp(z), default for
            :class:`~refine.model.parametrize.RegionModuli`: the equilibrium is rational-like in a
            modulus, with its pole at a negative one) or ``"z"``.
        xtol: stop when a step moves z by less.
    Returns:
        a :class:`~refine.optimize.result.RefineResult`; ``n_forward`` counts forward solves (one per
        iterate), ``n_gradient`` the series (one per iterate, ``order`` back-substitutions per
        frame each).
    """
    param, model = objective.param, objective.model
    if param.size != 1:
        raise FitError(f"pade_least_squares fits one unknown; this parametrisation has {param.size} "
                         "(use tensor_least_squares() or least_squares())")
    reg = param.regularization(np.zeros(1))
    if not (isinstance(reg, float) and reg == 0.0):
        raise FitError("pade_least_squares() fits unregularised parametrisations")
    degree = order // 2 if degree is None else int(degree)
    if 2 * degree > order or degree < 1:
        raise FitError(f"pade_least_squares: a [{degree}/{degree}] approximant needs order >= {2 * degree}, "
                         f"got order {order}")
    variable = _variable(param, variable)
    z = float(np.asarray(param.z0 if z0 is None else z0, float).reshape(-1)[0])
    lo, hi = (bounds if bounds is not None else
              ((z - np.log(30.0), z + np.log(30.0)) if variable == "exp" else (z - 3.0, z + 3.0)))
    lo, hi = float(lo), float(hi)
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(desc=f"Pade least squares (order {order})", unit="solve")
    history, n_solve, n_series = [], 0, 0
    t0 = time.perf_counter()

    def solve(zz):
        nonlocal n_solve
        n_solve += 1
        theta = param.apply(objective.theta, jnp.array([zz]))
        U = model.solve_frames(theta)
        r = np.asarray(objective.residuals_of(model.at_points(U, theta)))
        misfit = 0.5 * float(r @ r) if np.all(np.isfinite(r)) else np.inf
        history.append({"step": len(history), "z": [zz], "misfit": misfit})
        if bar is not None:
            bar.update(1)
            bar.set_postfix(misfit=misfit)
        return U, r, misfit

    def series(zz, U, r):
        nonlocal n_series
        n_series += 1
        theta, path = _path(objective, zz, variable, order)
        C = [r]
        coeffs = []
        for f in range(model.obs.n_frames):
            th = {**theta, "u_D": model.prescribed(f)}
            coeffs.append(equilibrium_series(model.solver, U[f], th, path, order))
        coeffs = jnp.stack(coeffs, axis=1)  # (order, frames, nodes, dim): the points are linear in them
        at = model.at_points(coeffs.reshape(-1, *coeffs.shape[2:]), theta)
        C.extend(np.asarray(objective.weighted(a)) for a in at.reshape(order, -1, *at.shape[1:]))
        return np.stack(C)

    def to_t(zz):
        return np.exp(zz) - np.exp(z) if variable == "exp" else zz - z

    def to_z(t):
        return float(np.log(np.exp(z) + t)) if variable == "exp" else z + t

    U, r, misfit = solve(z)
    if not np.isfinite(misfit):
        raise FitError(f"pade_least_squares: the model cannot be solved at the start z0 = {z}")
    ok, message = False, f"stopped after {max_steps} steps"
    for _ in range(max_steps):
        C = series(z, U, r)
        t, predicted = pade_minimiser(C, degree, degree, to_t(lo), to_t(hi))
        history[-1]["pade_prediction"] = predicted
        step = to_z(t) - z
        if abs(step) < xtol:
            ok, message = True, "converged"
            break
        while True:
            trial = z + step
            U_new, r_new, new = solve(trial)
            if new < misfit or abs(step) < xtol:
                break
            step *= 0.5
        if not new < misfit:
            ok, message = True, "converged (no descent left)"
            break
        z, U, r, misfit = trial, U_new, r_new, new
        if abs(step) < xtol:
            ok, message = True, "converged"
            break
    if bar is not None:
        bar.close()
    objective.n_forward += n_solve
    objective.n_gradient += n_series
    return RefineResult(values={"z": np.array([z]), **param.values(np.array([z]))}, error=misfit,
                        n_forward=n_solve, n_gradient=n_series, seconds=time.perf_counter() - t0,
                        history=history, method=f"pade-least-squares-{order}", converged=ok, message=message)
