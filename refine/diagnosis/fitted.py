"""A fitted hypothesis (:class:`Fitted`), how one is fitted and scored, refitted on other points
with standard errors, and the initial model as the baseline every hypothesis is compared with.

A hypothesis is a way the initial model may be wrong: regions of other stiffness
(:mod:`refine.diagnosis.regions`), a hole (:mod:`refine.diagnosis.holes`) or a different material
law (:mod:`refine.diagnosis.laws`). Each builds its own model (a mesh that follows the shapes), is
fitted on the guide points chosen for fitting, and is scored on held-out guide points and by an
information criterion.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from refine.model.measured import MeasuredModel
from refine.model.objective import Compiled
from refine.optimize.levenberg_marquardt import levenberg_marquardt


@dataclass
class Fitted:
    """A fitted hypothesis.

    Attributes:
        cause: ``"none"``, ``"stiffer-region"``, ``"softer-region"``, ``"hole"``, ``"regions"`` or
            ``"material-law"``.
        k: number of fitted parameters.
        chi2_fit: whitened squared misfit on the fitting points; chi2_holdout: on held-out points.
        bic: chi2_fit + k ln(n_fit).
        predicted: displacements of all points ``(frames, n_points, dim)``.
        shapes: fitted shapes ``[(kind, cx, cy, a, b, angle, relative_elasticity)]``, kind
            ``"ellipse"`` (a, b semi-axes), ``"rectangle"`` (a, b half sides) or ``"hole"``.
        law: the material law of the model.
    """

    cause: str
    k: int
    chi2_fit: float
    chi2_holdout: float
    bic: float
    predicted: np.ndarray
    shapes: list = field(default_factory=list)
    law: str = ""
    result: object = None
    model: object = None
    theta: object = None
    compiled: object = None
    z: object = None
    shapes_from: object = None
    z_std: object = None
    remesh: object = None

    def describe(self) -> str:
        parts = [f"{s[0]} at ({s[1]:.1f}, {s[2]:.1f}) {'half sides' if s[0] == 'rectangle' else 'axes'} "
                 f"({s[3]:.1f}, {s[4]:.1f}) angle {np.degrees(s[5]):.0f} deg ratio {s[6]:.2f}" for s in self.shapes]
        return f"{self.cause} [{'; '.join(parts) or self.law}] chi2 {self.chi2_fit:.0f} holdout {self.chi2_holdout:.0f}"


def _chi2(pred, obs, points, sigma) -> float:
    meas = obs.displacements[:, points]
    ok = np.isfinite(meas).all(-1)
    r = ((pred[:, points] - np.nan_to_num(meas)) / sigma)[ok]
    return float(np.sum(r * r))


def _fit(cause, compiled: Compiled, fit_mask, hold_mask, sigma, z0=None, shapes_from=None, **kw) -> Fitted:
    """Fit by Levenberg-Marquardt on the fitting points, score on both sets."""
    res = levenberg_marquardt(compiled, fit_mask, sigma, z0=z0)
    z = np.asarray(res.values["z"])
    pred = compiled.predict(z)
    obs = compiled.model.obs
    chi2 = _chi2(pred, obs, fit_mask, sigma)
    n = int(np.isfinite(obs.displacements[:, fit_mask]).all(-1).sum()) * pred.shape[-1]
    k = compiled.param.size
    return Fitted(cause, k, chi2, _chi2(pred, obs, hold_mask, sigma), chi2 + k * np.log(max(n, 2)), pred,
                  shapes=shapes_from(z) if shapes_from else [], result=res, model=compiled.model,
                  theta=compiled.param.apply(compiled.theta, z), compiled=compiled, z=z,
                  shapes_from=shapes_from, **kw)


def refit(f: Fitted, points, hold_mask, sigma, max_remesh: int = 2, element: str = "tri3") -> Fitted:
    """The same hypothesis refitted on other points (e.g. all guide points), with the standard
    errors of its unknowns.

    A hypothesis with fitted shapes is remeshed at them first and refitted from there, again
    while its shapes still move by more than a fifth of the element size: a morph of the first
    mesh can only take a shape so far (its cells distort, then invert), which leaves a region
    fitted too small with too large a ratio, or a hole too small. The new meshes use ``element``
    (quadratic triangles are far less stiff in a strongly strained region than linear ones at
    the same size). Without shapes the compiled model is reused."""
    g = None
    if f.remesh is not None and f.shapes:
        start = f
        for _ in range(max(1, max_remesh)):
            try:
                h = f.remesh(start.shapes, points, hold_mask, element)
            except Exception:  # noqa: BLE001 - e.g. a remesh at a runaway ratio that no longer solves
                h = None
            if h is None or not np.isfinite(h.chi2_fit):
                break
            if g is None or h.chi2_fit < g.chi2_fit:
                g = h
            moved = max(_moved(a, b) for a, b in zip(start.shapes, h.shapes))
            if moved < 0.2 * f.model.h:
                break
            start = h
    if g is None:  # no shapes, or no remesh could be fitted: refit the compiled model as it is
        g = _fit(f.cause, f.compiled, points, hold_mask, sigma, z0=f.z, shapes_from=f.shapes_from, law=f.law)
    g.z_std = standard_errors(g, points, sigma)
    return g


def _moved(s, t) -> float:
    """How far a fitted shape ``(kind, cx, cy, a, b, angle, ratio)`` moved: its largest change of
    centre or axis, or of the outline by its turn (``|a - b|`` times the angle)."""
    turn = abs(np.angle(np.exp(2j * (t[5] - s[5])))) / 2 * abs(t[3] - t[4])
    return float(max(np.max(np.abs(np.subtract(s[1:5], t[1:5]))), turn))


def standard_errors(f: Fitted, points, sigma) -> np.ndarray:
    """Standard errors of the fitted unknowns z from the Gauss-Newton covariance
    (J^T J)^-1 scaled by the reduced chi^2 (at least 1): how well the data fix each one."""
    obs = f.compiled.model.obs
    valid = np.isfinite(obs.displacements[:, points]).all(-1)
    J = f.compiled.jacobian(f.z)[:, points][valid].reshape(-1, len(f.z)) / sigma
    n, k = J.shape
    scale = max(f.chi2_fit / max(n - k, 1), 1.0)
    try:
        return np.sqrt(np.clip(np.diag(np.linalg.inv(J.T @ J)), 0, None) * scale)
    except np.linalg.LinAlgError:
        return np.full(k, np.nan)


def baseline(model: MeasuredModel, fit_mask, hold_mask, sigma) -> Fitted:
    """The initial model, nothing fitted (under pure displacement driving a uniform modulus
    cancels out, so there is nothing to fit without measured forces)."""
    pred = np.asarray(model.predict(model.params()))
    chi2 = _chi2(pred, model.obs, fit_mask, sigma)
    return Fitted("none", 0, chi2, _chi2(pred, model.obs, hold_mask, sigma), chi2, pred, law=model.experiment.law,
                  model=model, theta=model.params())


class NotApplicable(ValueError):
    """A hypothesis the data rule out before any fit (e.g. a hole where material was tracked)."""
