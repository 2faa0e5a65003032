"""Fitting a model's parameters to the measured guide points, by exact gradients.

An :class:`Objective` joins a :class:`~refine.model.MeasuredModel`, a parametrisation and a set
of measured points (the guide set, by default): its residuals are the noise-weighted differences
between predicted and measured displacements over all frames (lost points removed), and its
value is half their squared norm plus the parametrisation's regulariser.

- :func:`least_squares`: Gauss-Newton or Levenberg-Marquardt (optimistix) with exact Jacobians
  (one tangent solve per parameter and frame), for a handful of parameters.
- :func:`lbfgsb`: bounded L-BFGS (SciPy) on the scalar objective with adjoint gradients (one
  adjoint solve per frame, whatever the number of parameters), for fields.
- :func:`pade_least_squares` (from :mod:`refine.pade`): one unknown, Pade steps on the
  equilibrium's Taylor series (one forward solve per step, and a step reaches a minimiser a
  factor ten away).
- :func:`tensor_least_squares` (from :mod:`refine.tensor`): third-order Taylor models of the
  residuals, for fewest forward solves on one or a few unknowns.

Both return the library's common :class:`~refine.result.RefineResult`.
"""

from __future__ import annotations

import time

import jax
import jax.numpy as jnp
import numpy as np

from .errors import displacement_error
from .model import MeasuredModel
from .parametrize import feasible
from .result import RefineResult


class Objective:
    """Noise-weighted misfit of a parametrised model on one role's points.

    Args:
        model: the measured model.
        param: a parametrisation (see :mod:`refine.parametrize`).
        theta: base parameters (default: the model's initial ones).
        role: which points are matched (``"guide"``; a subset mask may be given as ``points``).
        points: optional boolean mask over all points overriding ``role``.
        noise_std: weight of the residuals (default: the bundle's noise, or 1).
    """

    def __init__(self, model: MeasuredModel, param, theta=None, role: str = "guide", points=None,
                 noise_std: float | None = None):
        self.model, self.param = model, param
        self.theta = model.params() if theta is None else theta
        obs = model.obs
        self.points = obs.mask(role) if points is None else np.asarray(points, bool)
        meas = obs.displacements[:, self.points]
        self.valid = np.isfinite(meas).all(axis=-1)  # (frames, points)
        self.measured = jnp.asarray(np.nan_to_num(meas))
        sigma = noise_std if noise_std is not None else (model.experiment.noise_std or 0.0)
        self.sigma = float(sigma) if sigma and sigma > 0 else 1.0
        self.n_forward = 0
        self.n_gradient = 0

    @property
    def n_residuals(self) -> int:
        return int(self.valid.sum()) * self.model.mesh.dim

    def predict(self, z):
        """Predicted displacements of all points ``(frames, n_points, dim)``."""
        return self.model.predict(self.param.apply(self.theta, z))

    def residuals(self, z):
        """``(n_residuals,)`` noise-weighted residuals over matched, tracked points."""
        return self.residuals_of(self.predict(z))

    def residuals_of(self, predicted):
        """The residuals of predicted displacements of all points ``(frames, n_points, dim)``
        (for a caller that solved already)."""
        r = (predicted[:, self.points] - self.measured) / self.sigma
        return r[self.valid].reshape(-1)

    def weighted(self, values):
        """Point values ``(frames, n_points, dim)`` noise-weighted at the matched, tracked points,
        ``(n_residuals,)``: the residuals' linear part (e.g. a series of predicted displacements)."""
        return (values[:, self.points] / self.sigma)[self.valid].reshape(-1)

    def value(self, z):
        r = self.residuals(z)
        return 0.5 * jnp.sum(r * r) + self.param.regularization(z)

    def paper_error(self, z) -> float:
        """The paper's eq. (1): sum of distances between predicted and measured positions."""
        pred = np.asarray(self.predict(z))[:, self.points]
        meas = np.where(self.valid[..., None], np.asarray(self.measured), np.nan)
        return displacement_error(pred, meas).value

    def _count(self, kind: str):
        def bump():
            if kind == "forward":  # one evaluation of the model over all frames, as a search counts it
                self.n_forward += 1
            else:
                self.n_gradient += 1

        jax.debug.callback(bump)


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
    value_and_grad = objective.__dict__.get("_value_and_grad")
    if value_and_grad is None:  # compiled once per objective, so later fits are warm
        value_and_grad = objective._value_and_grad = jax.jit(jax.value_and_grad(objective.value))

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


class Compiled:
    """A model and parametrisation with its prediction and Jacobian compiled once, together, for
    all points: fits on different point sets (fit, held-out, all guide points) and scoring then
    reuse the same compiled code. ``evaluate(z) -> (prediction, jacobian)`` with shapes
    ``(frames, points, dim)`` and ``(frames, points, dim, k)`` (forward mode: one tangent solve
    per unknown and frame at the converged state, next to the forward solve); ``predict`` and
    ``jacobian`` are its halves.

    One program, not two: a hypothesis' model is compiled once per mesh, and compiling the
    prediction apart from its Jacobian cost as much again (measured: 3.7 s of 12 s per fit on a
    ~1,200-node mesh), while the tangent solves add little to a solve (one back-substitution per
    unknown)."""

    def __init__(self, model: MeasuredModel, param, theta=None):
        self.model, self.param = model, param
        self.theta = model.params() if theta is None else theta
        f = lambda z: model.predict(param.apply(self.theta, z))  # noqa: E731
        self._evaluate = jax.jit(jax.jacfwd(lambda z: (f(z), f(z)), has_aux=True))
        self._last = None

    def evaluate(self, z) -> tuple[np.ndarray, np.ndarray]:
        z = np.asarray(z, float)
        if self._last is None or not np.array_equal(self._last[0], z):
            J, pred = self._evaluate(jnp.asarray(z))
            self._last = (z.copy(), np.asarray(pred), np.asarray(J))
        return self._last[1], self._last[2]

    def predict(self, z) -> np.ndarray:
        return self.evaluate(z)[0]

    def jacobian(self, z) -> np.ndarray:
        return self.evaluate(z)[1]


def levenberg_marquardt(compiled: Compiled, points, sigma: float, z0=None, max_steps: int = 30,
                        rtol: float = 1e-6, chi2_tol: float = 0.05) -> RefineResult:
    """Levenberg-Marquardt with exact Jacobians on ``compiled`` (see :class:`Compiled`), matching
    the ``points`` mask. The same algorithm as :func:`least_squares` with the compiled pieces
    reused across calls. Every evaluation (a step tried) is a forward solve with its Jacobian
    (:meth:`Compiled.evaluate`), so a rejected step costs one evaluation and an accepted one needs
    no other; a step the parametrisation calls infeasible (:func:`refine.parametrize.feasible`:
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
            if feasible(compiled.param, z + dz):
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


from .pade import pade_least_squares  # noqa: E402,F401  (re-exported: one import for every fit)
from .tensor import tensor_least_squares  # noqa: E402,F401
