"""A fitted hypothesis (:class:`Fitted`), how one is fitted and scored, refitted on other points
with standard errors, and the initial model as the baseline every hypothesis is compared with.

A hypothesis (:class:`Hypothesis`) is a way the initial model may be wrong: regions of other
stiffness (:mod:`refine.diagnosis.regions`), a hole (:mod:`refine.diagnosis.holes`) or a different
material law (:mod:`refine.diagnosis.laws`). Each builds its own model (a mesh that follows the
shapes), is fitted on the guide points chosen for fitting, and is scored on held-out guide points
and by an information criterion.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np
from jaxtyping import Bool, Float

from refine.diagnosis.shapes import Hole, RegionShape, report_row
from refine.diagnosis.uncertainty import drive_covariance, shape_errors
from refine.exceptions import RefineError
from refine.measures import Residuals
from refine.model.measured import MeasuredModel
from refine.model.objective import Compiled
from refine.optimize.levenberg_marquardt import levenberg_marquardt
from refine.optimize.result import RefineResult

Shape = RegionShape | Hole
Mask = Bool[np.ndarray, "n_points"]


class NotApplicable(RefineError, ValueError):
    """A hypothesis the data rule out before any fit (e.g. a hole where material was tracked)."""


class Hypothesis(Protocol):
    """What is tried: its cause, its material law, the shapes it reads from fitted unknowns, and
    (where it has shapes) the same hypothesis remeshed at fitted shapes.

    Regions and holes also say how their model and parametrisation are built (``build``)."""

    law: str
    remeshable: bool

    def cause_of(self, shapes: tuple[Shape, ...]) -> str:
        """The cause the fitted ``shapes`` name (``"none"``, ``"stiffer-region"``,
        ``"softer-region"``, ``"regions"``, ``"hole"`` or ``"material-law"``)."""

    def shapes_at(self, compiled: Compiled, z: np.ndarray) -> tuple[Shape, ...]:
        """The shapes at the fitted unknowns ``z`` (none for a material law)."""

    def at(self, shapes: tuple[Shape, ...], element: str) -> Hypothesis | None:
        """The same hypothesis on a new mesh of ``element`` built at ``shapes`` (None: it has no
        shapes to remesh at)."""


@dataclass(frozen=True)
class Unchanged:
    """The initial model, or another homogeneous law (``cause`` ``"material-law"``): no shapes."""

    law: str
    cause: str = "none"
    remeshable = False

    def cause_of(self, shapes) -> str:
        return self.cause

    def shapes_at(self, compiled, z) -> tuple:
        return ()

    def at(self, shapes, element) -> None:
        return None


def material_law(law: str) -> Unchanged:
    """The hypothesis that the material follows ``law``."""
    return Unchanged(law, "material-law")


@dataclass(frozen=True, eq=False)
class Fitted:
    """A fitted hypothesis.

    Attributes:
        hypothesis: what was fitted.
        k: number of fitted parameters.
        chi2_fit: whitened squared misfit on the fitting points; chi2_holdout: on held-out points.
        bic: chi2_fit + k ln(n_fit).
        predicted: displacements of all points ``(frames, n_points, dim)``.
        model: the model fitted (its mesh follows the shapes); theta: its fitted parameters.
        sigma: the noise the residuals were weighted with (length unit).
        shapes: the fitted shapes (none for a material law or the initial model).
        compiled, z, result: the compiled model, its fitted unknowns and the fit (None for the
            initial model); z_std: standard errors of z and z_cov ``(k, k)`` their covariance
            (after :func:`refit`; :mod:`refine.diagnosis.uncertainty` carries it to the shapes).
        q_disc: discretisation errors of the shapes' quantities ``(shapes, 7)``
            (:func:`~refine.diagnosis.uncertainty.with_discretisation`), None where not estimated;
            q_disc_parts: its parts by source (``"mesh"``, ``"drive"``), each ``(shapes, 7)``;
            q_disc_signed: the mesh's part with its sign ``(shapes, 7)`` (the coarser refit's change);
            q_disc_refits: the refits behind it where a hypothesis keeps them (a solid's hole:
            :func:`refine.solid.hole_area.with_plan_and_layers`).
    """

    hypothesis: Hypothesis
    k: int
    chi2_fit: float
    chi2_holdout: float
    bic: float
    predicted: Float[np.ndarray, "frames n_points dim"]
    model: MeasuredModel
    theta: dict
    sigma: float
    shapes: tuple[Shape, ...] = ()
    compiled: Compiled | None = None
    z: Float[np.ndarray, "k"] | None = None
    result: RefineResult | None = None
    z_std: Float[np.ndarray, "k"] | None = None
    z_cov: Float[np.ndarray, "k k"] | None = None
    q_disc: Float[np.ndarray, "shapes 7"] | None = None
    q_disc_parts: dict | None = None
    q_disc_signed: Float[np.ndarray, "shapes 7"] | None = None
    q_disc_refits: object | None = None

    @property
    def cause(self) -> str:
        return self.hypothesis.cause_of(self.shapes)

    @property
    def law(self) -> str:
        return self.hypothesis.law

    def describe(self) -> str:
        parts = [s.describe() for s in self.shapes]
        return f"{self.cause} [{'; '.join(parts) or self.law}] chi2 {self.chi2_fit:.0f} holdout {self.chi2_holdout:.0f}"


@dataclass(frozen=True)
class Failed:
    """A hypothesis that could not be fitted: ``name`` (what the search tried, e.g. ``"hole"``,
    ``"rectangle turned"``, a law's name), ``cause`` (what it would have named), and its reason,
    the kind of ``error`` (the exception's class name) and its ``message``. The report lists it as
    a row of the hypotheses table, and the search goes on with the others."""

    name: str
    cause: str
    error: str
    message: str

    @classmethod
    def of(cls, name: str, cause: str, e: BaseException) -> Failed:
        return cls(name, cause, type(e).__name__, str(e))

    def describe(self) -> str:
        return f"{self.name} failed ({self.error}: {self.message})"

    def row(self) -> dict:
        """The row of report.json's hypotheses table: no score, the reason instead."""
        return {"cause": self.cause, "tried": self.name, "k": None, "bic": None, "chi2_fit": None,
                "chi2_holdout": None, "law": None, "shapes": [], "kinds": [],
                "failed": {"error": self.error, "message": self.message}}


def hypothesis_rows(tried, failed=()) -> list[dict]:
    """report.json's hypotheses table: a row per fitted hypothesis of ``tried`` (its cause,
    unknowns, scores, law and shapes), then a row per :class:`Failed` one of ``failed``."""
    rows = [{"cause": f.cause, "k": f.k, "bic": f.bic, "chi2_fit": f.chi2_fit, "chi2_holdout": f.chi2_holdout,
             "law": f.law, "shapes": [report_row(s) for s in f.shapes], "kinds": [s.kind for s in f.shapes]}
            for f in tried]
    return rows + [f.row() for f in failed]


def fit_compiled(hypothesis: Hypothesis, compiled: Compiled, fit_mask: Mask, hold_mask: Mask, sigma: float,
                 z0=None, max_steps: int = 30) -> Fitted:
    """Fit ``compiled`` by Levenberg-Marquardt (at most ``max_steps`` evaluations) on the fitting
    points, score on both sets."""
    res = levenberg_marquardt(compiled, fit_mask, sigma, z0=z0, max_steps=max_steps)
    z = np.asarray(res.values["z"])
    pred = compiled.predict(z)
    fit, hold = (Residuals.at(compiled.model.obs.displacements, m, sigma) for m in (fit_mask, hold_mask))
    chi2, k = fit.chi2(pred), compiled.param.size
    return Fitted(hypothesis, k, chi2, hold.chi2(pred), chi2 + k * np.log(max(fit.n, 2)), pred, compiled.model,
                  compiled.theta_at(z), sigma, shapes=hypothesis.shapes_at(compiled, z),
                  compiled=compiled, z=z, result=res)


def fit(hypothesis, fit_mask: Mask, hold_mask: Mask, sigma: float) -> Fitted:
    """Build ``hypothesis``' model (a region or hole hypothesis) and fit it."""
    compiled, z0 = hypothesis.build()
    return fit_compiled(hypothesis, compiled, fit_mask, hold_mask, sigma, z0=z0)


def refit(f: Fitted, points: Mask, hold_mask: Mask, sigma: float, max_remesh: int = 2,
          element: str = "tri3", remesh: bool = True) -> Fitted:
    """The same hypothesis refitted on other points (e.g. all guide points), with the standard
    errors of its unknowns: remeshed at its fitted shapes first (:func:`settle`; not with
    ``remesh`` False, e.g. for a fit settled on fewer frames); without shapes, or where no
    remesh could be fitted, the compiled model is refitted as it is."""
    g = settle(f, points, hold_mask, sigma, max_remesh, element) if remesh else None
    if g is None:  # no shapes, or no remesh could be fitted: refit the compiled model as it is
        g = fit_compiled(f.hypothesis, f.compiled, points, hold_mask, sigma, z0=f.z)
    cov = covariance(g, points, sigma) + drive_covariance(g, points, sigma)  # noise of the drive too
    return replace(g, z_std=np.sqrt(np.clip(np.diag(cov), 0, None)), z_cov=cov)


def settle(f: Fitted, points: Mask, hold_mask: Mask, sigma: float, max_remesh: int = 2,
           element: str = "tri3") -> Fitted | None:
    """A hypothesis with fitted shapes remeshed at them and refitted from there on ``points``
    (the best of the remeshed fits; None without shapes or where no remesh could be fitted),
    again while its shapes still move by more than a fifth of the element size, or by more than
    their standard errors where the data fix them better (:func:`_settled`): a morph of the first
    mesh can only take a shape so far (its cells distort, then invert), which leaves a region
    fitted too small with too large a ratio, or a hole too small. The new meshes use
    ``element`` (quadratic triangles are far less stiff in a strongly strained region than
    linear ones at the same size)."""
    if not (f.shapes and f.hypothesis.remeshable):
        return None
    g, start = None, f
    for _ in range(max(1, max_remesh)):
        try:
            h = fit(f.hypothesis.at(start.shapes, element), points, hold_mask, sigma)
        except Exception:  # noqa: BLE001 - e.g. a remesh at a runaway ratio that no longer solves
            h = None
        if h is None or not np.isfinite(h.chi2_fit):
            break
        if g is None or h.chi2_fit < g.chi2_fit:
            g = h
        moved = max(a.moved(b) for a, b in zip(start.shapes, h.shapes))
        if moved < _settled(h, points, sigma, 0.2 * f.model.h):
            break
        start = h
    return g


def _settled(f: Fitted, points: Mask, sigma: float, coarse: float) -> float:
    """How little a remesh must move ``f``'s shapes (length unit) for the fit to count as
    settled: ``coarse`` (a fifth of the first mesh's element size), or the largest standard error
    of a centre or axis where the data fix the shapes better. A fit on a morphed mesh can stop
    short where the morph would squash cells; a fresh mesh lets it go on."""
    errors = shape_errors(replace(f, z_cov=covariance(f, points, sigma))) or ()
    lengths = [v for e in errors for v in (*e.centroid, *e.axes) if np.isfinite(v)]
    return min(coarse, max(lengths)) if lengths else coarse


def covariance(f: Fitted, points: Mask, sigma: float) -> Float[np.ndarray, "k k"]:
    """Covariance of the fitted unknowns z: the Gauss-Newton (J^T J)^-1 scaled by the reduced
    chi^2 (at least 1, so a misfit above the noise widens it); NaN where J^T J is singular."""
    J = Residuals.at(f.compiled.model.obs.displacements, points, sigma).jacobian(f.compiled.jacobian(f.z))
    n, k = J.shape
    scale = max(f.chi2_fit / max(n - k, 1), 1.0)
    try:
        return np.linalg.inv(J.T @ J) * scale
    except np.linalg.LinAlgError:
        return np.full((k, k), np.nan)


def standard_errors(f: Fitted, points: Mask, sigma: float) -> Float[np.ndarray, "k"]:
    """Standard errors of the fitted unknowns z (:func:`covariance`): how well the data fix each one."""
    return np.sqrt(np.clip(np.diag(covariance(f, points, sigma)), 0, None))


def baseline(model: MeasuredModel, fit_mask: Mask, hold_mask: Mask, sigma: float, predicted=None) -> Fitted:
    """The initial model, nothing fitted (under pure displacement driving a uniform modulus
    cancels out, so there is nothing to fit without measured forces); ``predicted`` its
    predictions ``(frames, n_points, dim)`` where the caller has them (default: solved here)."""
    pred = np.asarray(model.predict(model.params()) if predicted is None else predicted)
    fit, hold = (Residuals.at(model.obs.displacements, m, sigma) for m in (fit_mask, hold_mask))
    chi2 = fit.chi2(pred)
    return Fitted(Unchanged(model.experiment.law), 0, chi2, hold.chi2(pred), chi2, pred, model, model.params(), sigma)
