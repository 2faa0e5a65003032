"""The 3D diagnosis of a solid body without a cavity (a block held by grips; issue 23's "stiff
inclusion in a block"): is anything wrong beyond the noise (the null test on the ``guide``
points), where (the regularised modulus field on the model's mesh, :mod:`refine.solid.field`), is
it an ellipsoidal inclusion (:mod:`refine.solid.inclusion`, fitted by exact gradients, then
refitted on the block graded fine around it, :mod:`refine.solid.inclusion_mesh`, with standard
errors and its ratio's profile), how much better the held-out ``validate`` points are predicted; the report.

The model is the bundle's mesh as it is (``domain = { mesh = ... }``), driven by its ``boundary``
points (e.g. markers on the grips' jaws) with the experiment's law, ``E`` and ``nu``; under pure
displacement driving only moduli relative to the background are identifiable. An inclusion is
reported where it lowers the BIC and the held-out misfit both.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

import jaxfem as jf

from refine.bundle.io import Bundle
from refine.diagnosis.fitted import Fitted, baseline, covariance, fit, fit_compiled
from refine.diagnosis.noise import estimate_noise
from refine.diagnosis.uncertainty import drive_covariance
from refine.exceptions import ObservationError
from refine.model.measured import MeasuredModel
from refine.solid.field import Field, modulus_field
from refine.solid.initial import checked_baseline
from refine.solid.inclusion import MAX_LOG_RATIO, Inclusion, ellipsoid_errors
from refine.solid.inclusion_mesh import FocusedMesh, focus_of, refit_focused
from refine.solid.inclusion_profile import Profile, profile_ratio, profiled_fit, strength
from refine.solid.inclusion_total import Discretisation, discretisation_refit, total_intervals, values_of


@dataclass(frozen=True)
class InclusionConfig:
    """Settings of a solid body's diagnosis: ``alpha`` the null test's level, ``max_candidates``
    field regions tried as inclusions, the field's smoothing ``field_weight`` (x residuals per
    cell) and ``field_iterations`` (L-BFGS-B; 45: the field only places the start, the fit on the
    graded mesh does the rest), ``linear_solver``; whether the finding's ratio is
    ``profile``d (:func:`refine.solid.inclusion_profile.profile_ratio`: the interval where chi^2
    rises by at most ``profile_threshold`` times the reduced chi^2, at most ``profile_steps`` refits
    per side); ``fit_mesh``: a finer mesh of the same body on which the inclusions are fitted and
    profiled (and the initial model they are compared with solved again), the field staying on the
    bundle's (None: the bundle's mesh throughout; a coarse model biases the volume low);
    ``focus``: without ``fit_mesh``, the
    inclusion found on the bundle's mesh is refitted and profiled on the body's box graded fine
    around it (:func:`refine.solid.inclusion_mesh.refit_focused`; None: not; a body that is no box
    keeps its mesh); where the profile finds a point more than ``restart_tol`` below the fit in
    chi^2 (the fit stopped short along the valley), the fit is refitted from there (at most
    ``refit_steps`` evaluations) and
    profiled again, at most ``restart_profiles`` times
    (:func:`refine.solid.inclusion_profile.profiled_fit`); ``discretisation``: the graded fit's
    discretisation error is estimated by its refit on the box graded over the same region with
    spacings this factor times larger, and the report's ``total`` intervals hold it
    (:mod:`refine.solid.inclusion_total`; None: not, the profile's intervals alone)."""

    alpha: float = 0.01
    max_candidates: int = 2
    field_weight: float = 2.0
    field_iterations: int = 45
    linear_solver: str = "auto"
    profile: bool = True
    profile_threshold: float = 4.0
    profile_steps: int = 4
    fit_mesh: jf.Mesh | None = None
    focus: FocusedMesh | None = FocusedMesh()
    restart_tol: float = 0.5
    restart_profiles: int = 1
    refit_steps: int = 10
    discretisation: float | None = float(np.sqrt(2.0))


@dataclass
class InclusionDiagnosis:
    """What a solid body's diagnosis found: the initial model's fit ``base``, the ``null`` test,
    the modulus ``field`` (None where the null test passed), the inclusions fitted
    (``candidates``), the best (``inclusion``) and the chosen fit (``chosen``: it or ``base``),
    seconds per stage, the ``profile`` and the ``starts`` of the fit reported (the last:
    :func:`refine.solid.inclusion_profile.profiled_fit`), the graded fit's ``discretisation``
    error (None: not estimated)."""

    base: Fitted
    null: object
    field: Field | None
    candidates: list
    inclusion: Fitted | None
    chosen: Fitted
    seconds: dict = field(default_factory=dict)
    profile: Profile | None = None
    starts: list = field(default_factory=list)
    discretisation: Discretisation | None = None

    @property
    def found(self) -> bool:
        return self.chosen is not self.base


def fills_hull(mesh: jf.Mesh, fraction: float = 0.97) -> bool:
    """Whether a 3D mesh fills at least ``fraction`` of its convex hull: a body without a cavity
    (a block), which :func:`refine.solid.diagnose_solid` diagnoses for an inclusion, unlike a cup
    holder (two thirds of its hull), whose bottom it diagnoses for a hole."""
    from scipy.spatial import ConvexHull

    return bool(mesh.volumes().sum() >= fraction * ConvexHull(mesh.nodes).volume)


def body_model(bundle: Bundle, cfg: InclusionConfig) -> MeasuredModel:
    """The initial model of a solid bundle: its mesh file, driven by its boundary points."""
    exp, obs = bundle.experiment, bundle.observations
    if exp.kind != "solid" or obs is None or obs.dim != 3:
        raise ObservationError("the 3D diagnosis takes a solid bundle with 3D points (x, y, z; ux, uy, uz)")
    for role in ("boundary", "guide", "validate"):
        if not (obs.roles == role).any():
            raise ObservationError(f"no {role} point: a solid body's diagnosis needs boundary points that drive it, "
                                   "guide points to fit and validate points to check")
    root = "" if bundle.root is None else f"{bundle.root}/"
    mesh = jf.read_mesh(f"{root}{exp.domain.path}")
    return MeasuredModel(exp, obs, mesh=mesh, linear_solver=cfg.linear_solver)


def with_errors(f: Fitted, points, sigma: float) -> Fitted:
    """``f`` with the covariance of its unknowns: Gauss-Newton on ``points``, plus the drive's
    noise (:func:`refine.diagnosis.uncertainty.drive_covariance`)."""
    cov = covariance(f, points, sigma) + drive_covariance(f, points, sigma)
    return replace(f, z_std=np.sqrt(np.clip(np.diag(cov), 0, None)), z_cov=cov)


def profiled(f: Fitted, guide, validate, sigma: float, cfg, focused: bool, log=print):
    """``f``'s ratio profiled and the fit restarted from a lower profile point
    (:func:`refine.solid.inclusion_profile.profiled_fit`) with ``cfg``'s ``profile_threshold``,
    ``profile_steps``, ``refit_steps``, ``restart_tol`` and ``restart_profiles``; the first
    start is named ``"graded refit"`` where ``focused``, else ``"fit"``. Returns the fit
    reported, the profile and the starts."""

    def profile(g):
        return profile_ratio(g, guide, sigma, cfg.profile_threshold, cfg.profile_steps, log=log)

    def refit(g, z):
        h = fit_compiled(g.hypothesis, g.compiled, guide, validate, sigma, z0=z, max_steps=cfg.refit_steps)
        return with_errors(h, guide, sigma)

    best, prof, starts = profiled_fit(f, profile, refit, cfg.restart_tol, cfg.restart_profiles, log=log)
    starts[0]["start"] = "graded refit" if focused else "fit"
    return best, prof, starts


def diagnose_inclusion(bundle: Bundle, cfg: InclusionConfig = InclusionConfig(), log=print) -> InclusionDiagnosis:
    """Diagnose a solid body for an ellipsoidal inclusion (see the module)."""
    t0 = time.perf_counter()
    model = body_model(bundle, cfg)
    obs = model.obs
    guide, validate = obs.roles == "guide", obs.roles == "validate"
    sigma = bundle.experiment.noise_std or estimate_noise(obs)
    base, null = checked_baseline(model, obs, sigma)
    seconds = {"initial": time.perf_counter() - t0}
    log(f"model: {model.mesh.n_cells} {model.mesh.element} cells, {len(obs.ids)} points; misfit {null.ratio:.2f} x "
        f"the noise's (p = {null.p_value:.2g})")
    fld, tried, best = None, [], None
    if null.p_value < cfg.alpha:
        fld = modulus_field(model, sigma, guide, cfg.field_weight, cfg.field_iterations, cfg.max_candidates)
        seconds["field"] = fld.seconds
        log(f"  modulus field: {len(fld.blobs)} regions ({fld.gradients} gradients, {fld.seconds:.0f} s)")
        if cfg.fit_mesh is not None:  # the fits on the finer mesh, against its own initial model
            model = MeasuredModel(bundle.experiment, obs, mesh=cfg.fit_mesh, linear_solver=cfg.linear_solver)
            base = baseline(model, guide, validate, sigma)
        for blob in fld.blobs:
            f = fit(Inclusion.from_blob(model, blob), guide, validate, sigma)
            tried.append(f)
            log(f"  {f.describe()}")
            if np.isfinite(f.chi2_fit) and (best is None or f.chi2_fit < best.chi2_fit):
                best = f
        seconds["inclusion"] = time.perf_counter() - t0 - sum(seconds.values())
    chosen, focused, region = base, False, None
    if best is not None and best.bic < base.bic and best.chi2_holdout < base.chi2_holdout:
        if cfg.fit_mesh is None and cfg.focus is not None:  # refitted where the coarse model's bias is
            t1 = time.perf_counter()
            region = focus_of(best.shapes[0])
            fine_base, g = refit_focused(best, guide, validate, sigma, cfg.focus, region=region)
            if g is not None and np.isfinite(g.chi2_fit):
                base, best, focused = fine_base, g, True
                log(f"  on a graded mesh ({g.model.mesh.n_cells} cells): {g.describe()}")
            seconds["focus"] = time.perf_counter() - t1
        best = chosen = with_errors(best, guide, sigma)
    prof, starts = None, []
    if chosen is not base and cfg.profile:
        t1 = time.perf_counter()
        best, prof, starts = profiled(chosen, guide, validate, sigma, cfg, focused, log)
        chosen = best
        seconds["profile"] = time.perf_counter() - t1
        log(f"  ratio {prof.ratio[0]:.3g}-{prof.ratio[1]:.3g}, volume {prof.volume[0]:.0f}-{prof.volume[1]:.0f} "
            f"(profile, {prof.evaluations} solves)")
    disc = None
    if chosen is not base and focused and cfg.discretisation:  # the graded mesh's bias, by a coarser refit
        t1 = time.perf_counter()
        disc = discretisation_refit(chosen, guide, validate, sigma, cfg.focus, region, cfg.discretisation)
        seconds["discretisation"] = time.perf_counter() - t1
        log("  discretisation: no estimate (the coarser refit failed)" if disc is None else
            f"  discretisation ({disc.cells} cells, x{disc.factor:.3g}): errors of log ratio "
            f"{disc.errors['log_ratio']:.3g}, volume {disc.errors['volume']:.0f}, strength {disc.errors['strength']:.0f}")
    seconds["total"] = time.perf_counter() - t0
    return InclusionDiagnosis(base, null, fld, tried, best, chosen, seconds, prof, starts, disc)


def inclusion_report(d: InclusionDiagnosis) -> dict:
    """report.json's content: the cause, the inclusion's centroid, semi-axes, axis directions,
    volume and relative elasticity with standard errors (``ratio_at_bound``: the fit ran to
    :data:`~refine.solid.inclusion.MAX_LOG_RATIO`, so the data fix only a bound on the ratio, and
    the volume is that of an all but rigid or empty inclusion acting alike: the standard errors,
    linearised there, do not hold), its ``strength`` (what the surface fixes:
    :func:`~refine.solid.inclusion_profile.strength`) and ``profile`` (the intervals of ratio,
    volume and strength where chi^2 rises by at most the threshold: these, not the linearised
    standard errors, cover the volume-ratio valley), ``fit_start`` (which start gave the fit: the
    graded refit, the fit, or a profile point lower than it) with all ``starts``, the
    ``coarse_fit`` where the fit was refitted on another mesh (the profile's intervals are the
    fit mesh's: a bias that mesh leaves they do not hold), the ``discretisation`` error of the
    graded fit and the ``total`` intervals that hold it (:mod:`refine.solid.inclusion_total`), the
    field's regions, the null test, the held-out gain, seconds."""
    obs = d.base.model.obs
    validate = obs.roles == "validate"
    n = max(1, 3 * obs.n_frames * int(validate.sum()))
    rms = lambda f: float(np.sqrt(f.chi2_holdout / n) * f.sigma)  # noqa: E731
    out = {"cause": d.chosen.cause, "null_test": {"statistic": d.null.statistic, "dof": d.null.dof,
                                                   "p_value": d.null.p_value, "noise_std": d.null.sigma},
           "model": {"cells": int(d.base.model.mesh.n_cells), "element": d.base.model.mesh.element,
                     "points": int(len(obs.ids))},
           "validate_rms": {"initial": rms(d.base)}, "findings": [], "seconds": d.seconds}
    if d.field is not None:
        out["field"] = {"gradients": d.field.gradients, "regions": [
            {"sign": b.sign, "centroid": b.centroid.tolist(), "axes": b.axes.tolist(), "volume": b.volume,
             "peak_ratio": b.ratio} for b in d.field.blobs]}
    if d.found:
        s = d.chosen.shapes[0]
        out["validate_rms"]["refined"] = rms(d.chosen)
        out["held_out_gain"] = out["validate_rms"]["initial"] / max(out["validate_rms"]["refined"], 1e-300)
        out["findings"].append({"kind": "inclusion", "cause": s.cause, "centroid": list(s.centre),
                                "axes": list(s.axes), "directions": [list(c) for c in np.asarray(s.rotation).T],
                                "volume": s.volume, "relative_elasticity": s.ratio, "std": ellipsoid_errors(d.chosen),
                                "ratio_at_bound": bool(abs(np.log(s.ratio)) > 0.95 * MAX_LOG_RATIO),
                                "strength": float(strength(s.volume, s.ratio, d.base.model.experiment.nu))})
        if d.profile is not None:  # the statistical intervals, and with the mesh's bias (the total)
            out["findings"][0]["profile"] = d.profile.as_dict()
            nu = d.base.model.experiment.nu
            out["findings"][0]["total"] = total_intervals(values_of(s, nu), out["findings"][0]["profile"], d.discretisation)
        if d.discretisation is not None:
            out["findings"][0]["discretisation"] = d.discretisation.as_dict()
        coarse = [c for c in d.candidates if c.shapes and c.model is not d.chosen.model and np.isfinite(c.chi2_fit)]
        if coarse:  # the fit on the bundle's mesh before the graded refit: how far the mesh moved it
            c = min(coarse, key=lambda g: g.chi2_fit).shapes[0]
            out["findings"][0]["coarse_fit"] = {
                "cells": int(coarse[0].model.mesh.n_cells), "centroid": list(c.centre), "volume": c.volume,
                "relative_elasticity": c.ratio, "strength": float(strength(c.volume, c.ratio, d.base.model.experiment.nu))}
        if d.starts:  # which start gave the reported fit (the last), and the ones before it
            out["findings"][0]["fit_start"] = d.starts[-1]["start"]
            out["findings"][0]["starts"] = d.starts
    return out


def diagnose_and_write(bundle: Bundle, out, cfg: InclusionConfig = InclusionConfig(),
                       quiet: bool = False) -> tuple[InclusionDiagnosis, dict]:
    """Diagnose a solid body (:func:`diagnose_inclusion`) and write ``OUT/report.json``
    (:func:`inclusion_report`); returns the diagnosis and the report."""
    import json
    from pathlib import Path

    log = (lambda m: None) if quiet else print
    d = diagnose_inclusion(bundle, cfg, log=log)
    rep = inclusion_report(d)
    Path(out).mkdir(parents=True, exist_ok=True)
    (Path(out) / "report.json").write_text(json.dumps(rep, indent=1), encoding="utf-8")
    f = rep["findings"][0] if rep["findings"] else None
    log(f"finding: {rep['cause']}" + (f" at {[round(v, 2) for v in f['centroid']]}, volume {f['volume']:.1f}, "
                                      f"x{f['relative_elasticity']:.3g}" if f else ""))
    return d, rep
