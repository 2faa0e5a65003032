"""The 3D diagnosis of any solid body: one engine for every mesh, looping over the registry's 3D
causes (:func:`refine.causes.causes`), so that a cause added as one file is tried without a word
here.

1. The initial model (the bundle's mesh as it is, driven by its boundary points:
   :func:`refine.solid.inclusion_diagnosis.body_model`) fitted on the guide points, its null test
   (:func:`refine.solid.initial.checked_baseline`) against the noise, its propagation from the
   drive and the model's own discretisation error (:func:`refine.solid.floor.discretisation_floor`),
   whose sum (``sigma_eff``) every later fit is weighed at, as the 2D diagnosis's.
2. Where it fails, candidate places (:func:`candidates`): the regions of the regularised modulus
   field (:mod:`refine.solid.field`) and, where points lie inside the volume, the gaps among them
   (softer candidates: cavities).
3. For each candidate every ``"place"`` cause's jobs, then every ``"reshape"`` cause's from each
   fit; then every ``"global"`` cause's (other material laws). A job that raises is a row of the
   hypotheses table with its reason (:class:`~refine.diagnosis.fitted.Failed`).
4. The choice as the 2D search makes it (:func:`refine.diagnosis.search._choose`: the lowest BIC
   plus held-out misfit among the fits that beat the initial model's BIC by ``bic_margin`` and
   lower its held-out misfit), only where the null test rejects the initial model.
5. The chosen region refitted on the body's box graded fine around it where the body is a box
   (:func:`refine.solid.inclusion_mesh.refit_focused`; another body keeps its mesh), standard
   errors, its ratio's profile and the graded mesh's discretisation error where its ratio is
   fitted (:mod:`refine.solid.inclusion_profile`, :mod:`refine.solid.inclusion_total`).

A failure after the initial model raises with ``e.incomplete``: a :class:`BodyDiagnosis` of what
was done (its report has ``incomplete``).
"""

from __future__ import annotations

import time
import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from refine.bundle.io import Bundle
from refine.causes import causes
from refine.diagnosis.fitted import Failed, Fitted, NotApplicable, hypothesis_rows
from refine.diagnosis.noise import NullTest, estimate_noise
from refine.diagnosis.search import _choose, _score
from refine.model.measured import MeasuredModel
from refine.solid.field import modulus_field
from refine.solid.gaps import gap_candidates, interior_points  # noqa: F401 - the engine's gap candidates
from refine.solid.inclusion import MAX_LOG_RATIO, ellipsoid_errors
from refine.solid.inclusion_diagnosis import body_model, profiled, with_errors
from refine.solid.inclusion_mesh import FocusedMesh, focus_of, refit_focused
from refine.solid.inclusion_profile import strength
from refine.solid.inclusion_total import discretisation_refit, total_intervals, values_of
from refine.solid.initial import checked_baseline


@dataclass(frozen=True)
class EngineConfig:
    """Settings of a solid body's diagnosis: the null test's ``alpha``; ``bic_margin`` (how much
    lower than the initial model's BIC a hypothesis must score); ``max_candidates`` places tried;
    the field's ``field_weight`` and ``field_iterations``; ``gaps``: whether gaps in the points
    inside the volume are candidates, a gap where no point lies within ``gap_factor`` times their
    median spacing; ``try_laws``: whether the ``"global"`` causes are tried; ``linear_solver``;
    ``model_error``: whether the null level holds the model's discretisation error (its mesh split
    in eight: one more compile and solve); ``focus`` (the graded refit of a box-shaped body,
    None: not; its spacings shrunk to at most ``focus_scale`` times the model's cell size:
    :func:`focus_for`), ``profile`` (the ratio's profile: ``profile_threshold``,
    ``profile_steps``, ``restart_tol``, ``restart_profiles``, ``refit_steps``), ``discretisation`` (the graded fit's coarser refit factor, None: not): as
    :class:`refine.solid.inclusion_diagnosis.InclusionConfig`."""

    alpha: float = 0.01
    bic_margin: float = 0.0
    max_candidates: int = 2
    field_weight: float = 2.0
    field_iterations: int = 45
    gaps: bool = True
    gap_factor: float = 1.5
    try_laws: bool = True
    model_error: bool = True
    linear_solver: str = "auto"
    focus: FocusedMesh | None = FocusedMesh()
    focus_scale: float = 0.625
    profile: bool = True
    profile_threshold: float = 4.0
    profile_steps: int = 4
    restart_tol: float = 0.5
    restart_profiles: int = 1
    refit_steps: int = 10
    discretisation: float | None = float(np.sqrt(2.0))

    def settings(self) -> dict:
        return {k: (v if isinstance(v, (int, float, str, bool, type(None))) else repr(v))
                for k, v in self.__dict__.items()}


@dataclass
class Search:
    """What a cause's jobs see (the 3D counterpart of :class:`refine.diagnosis.search.Trials`):
    the initial ``model``, the ``fit`` (guide) and ``hold`` (validate) masks, the noise ``sigma``,
    the settings ``cfg``, the ``null`` test, ``n_fit`` residuals, ``log``, the ``fitted`` and
    ``failed`` hypotheses so far, the initial fit ``base``."""

    model: MeasuredModel
    fit: np.ndarray
    hold: np.ndarray
    sigma: float
    cfg: EngineConfig
    null: NullTest
    n_fit: int
    log: Callable
    base: Fitted
    fitted: list = dataclasses.field(default_factory=list)
    failed: list = dataclasses.field(default_factory=list)
    pool: object = None

    def explains(self, f: Fitted) -> bool:
        return f.chi2_fit / max(self.n_fit, 1) < 1.5 * (1.0 + self.null.propagation)

    def attempt(self, cause, name: str, job) -> Fitted | None:
        """Run one job of ``cause``: its fit (kept in ``fitted``), or None where it does not apply or
        fails (a row in ``failed`` with its reason)."""
        try:
            f = job()
        except NotApplicable as e:
            self.log(f"  not tried: {name}: {e}")
            return None
        except Exception as e:  # noqa: BLE001 - a hypothesis that cannot be fitted is a row with its reason
            self.failed.append(Failed.of(name, cause.names[0] if cause.names else cause.name, e))
            self.log(f"  could not fit {name}: {type(e).__name__}: {e}")
            return None
        if not np.isfinite(f.chi2_fit):
            self.failed.append(Failed(name, f.cause, "NotFinite", "the fit's misfit is not a finite number"))
            self.log(f"  {name}: no finite misfit")
            return None
        self.fitted.append(f)
        self.log(f"  tried {name}: {f.describe()}")
        return f

    def jobs_of(self, cause, start) -> dict:
        """``cause``'s jobs from ``start``; a cause whose ``applies`` or ``jobs`` refuses is a row."""
        try:
            why = cause.applies(self)
            if why:
                self.log(f"  {cause.name} not tried: {why}")
                return {}
            return cause.jobs(self, start) or {}
        except Exception as e:  # noqa: BLE001
            self.failed.append(Failed.of(cause.name, cause.names[0] if cause.names else cause.name, e))
            return {}


def candidates(search: Search) -> tuple[list, object]:
    """The candidate places: the gaps among the points inside the volume first (where there are
    any), then the modulus field's regions; at most ``max_candidates`` of the field's. Returns
    them and the field."""
    cfg, found = search.cfg, []
    if cfg.gaps:
        found += gap_candidates(search.model, cfg.gap_factor)
        if found:
            search.log(f"  gaps in the interior points: {len(found)} regions")
    fld = modulus_field(search.model, search.sigma, search.fit, cfg.field_weight, cfg.field_iterations,
                        cfg.max_candidates)
    search.log(f"  modulus field: {len(fld.blobs)} regions ({fld.gradients} gradients, {fld.seconds:.0f} s)")
    return found + list(fld.blobs), fld


def search_causes(search: Search, places: list) -> None:
    """Every place cause from each candidate, every reshape cause from each fit, every global
    cause (see the module); the fits go to ``search.fitted``, the failures to ``search.failed``."""
    for c in places:
        search.log(f"candidate ({c.source}, {'stiffer' if c.sign > 0 else 'softer'}) at "
                   f"{np.round(c.centroid, 2).tolist()}")
        placed = []
        for cause in causes(3, "place"):
            for name, job in search.jobs_of(cause, c).items():
                placed.append(search.attempt(cause, name, job))
        for f in [p for p in placed if p is not None]:
            for cause in causes(3, "reshape"):
                for name, job in search.jobs_of(cause, f).items():
                    search.attempt(cause, name, job)
    if search.cfg.try_laws:
        for cause in causes(3, "global"):
            for name, job in search.jobs_of(cause, None).items():
                search.attempt(cause, name, job)


@dataclass(eq=False)
class BodyDiagnosis:
    """What a solid body's diagnosis found: the ``bundle``, its settings ``config``, the initial
    fit ``base`` (on the mesh the chosen fit is compared on) and ``null`` test, the
    ``candidates`` and the modulus field (``modulus``), the fits (``tried``) and ``failed`` hypotheses, the
    ``chosen`` fit (``base`` where nothing was found) and the one ``selected`` before its refit,
    the ``profile``, ``starts`` and ``discretisation`` of a profiled region, ``seconds`` per stage;
    ``incomplete`` (stage, error) for a run that stopped."""

    bundle: Bundle
    config: EngineConfig
    base: Fitted
    null: NullTest
    candidates: list = dataclasses.field(default_factory=list)
    modulus: object = None
    tried: list = dataclasses.field(default_factory=list)
    failed: list = dataclasses.field(default_factory=list)
    chosen: Fitted | None = None
    selected: Fitted | None = None
    profile: object = None
    starts: list = dataclasses.field(default_factory=list)
    discretisation: object = None
    coarse: Fitted | None = None
    search_base: Fitted | None = None
    seconds: dict = dataclasses.field(default_factory=dict)
    incomplete: tuple | None = None

    @property
    def found(self) -> bool:
        return self.chosen is not None and self.chosen is not self.base

    def report(self) -> dict:
        """report.json's content, schema 2 (:func:`refine.solid.engine_report.body_report`)."""
        from refine.solid.engine_report import body_report

        return body_report(self)

    def summary(self) -> str:
        from refine.solid.engine_report import body_summary

        return body_summary(self)

    def write(self, out) -> Path:
        """Write OUT/report.json (atomically), summary.txt and report.html; returns report.json's path."""
        from refine.solid.engine_report import write_body

        return write_body(self, out)


def diagnose_body(bundle: Bundle, config: EngineConfig | None = None, log=print) -> BodyDiagnosis:
    """Diagnose a solid bundle (see the module)."""
    cfg = config or EngineConfig()
    t0 = time.perf_counter()
    model = body_model(bundle, cfg)
    obs = model.obs
    guide, validate = obs.roles == "guide", obs.roles == "validate"
    sigma = bundle.experiment.noise_std or estimate_noise(obs)
    sigma_model = model_error(model, guide, log) if cfg.model_error else 0.0
    sigma_eff = float(np.hypot(sigma, sigma_model))
    base, null = checked_baseline(model, obs, sigma, sigma_model=sigma_model, fit_sigma=sigma_eff)
    d = BodyDiagnosis(bundle, cfg, base, null, search_base=base, seconds={"initial": time.perf_counter() - t0})
    log(f"model: {model.mesh.n_cells} {model.mesh.element} cells, {len(obs.ids)} points; noise {sigma:.3g}, model "
        f"discretisation error {sigma_model:.3g}; misfit {null.ratio:.2f} x its null level (p = {null.p_value:.2g})")
    search = Search(model, guide, validate, sigma_eff, cfg, null, 3 * obs.n_frames * int(guide.sum()), log, base,
                    failed=d.failed)
    stage = "the candidates"
    try:
        if null.p_value < cfg.alpha:
            d.candidates, d.modulus = candidates(search)
            d.seconds["candidates"] = time.perf_counter() - t0 - sum(d.seconds.values())
            stage = "the hypotheses"
            search_causes(search, d.candidates)
        elif cfg.try_laws:  # tried all the same (never chosen where the null test passes)
            stage = "the material laws"
            search_causes(search, [])
        d.tried = list(search.fitted)
        d.seconds["hypotheses"] = time.perf_counter() - t0 - sum(d.seconds.values())
        chosen = _choose(base, [base] + d.tried, cfg) if null.p_value < cfg.alpha else base
        d.chosen = d.selected = chosen
        if chosen is not base:
            log(f"chosen: {chosen.describe()}")
            stage = "the chosen fit's refit"
            _refine(d, search, log)
    except BaseException as e:
        d.tried = list(search.fitted)
        d.chosen = d.chosen or base
        d.incomplete = (stage, e)
        d.seconds["total"] = time.perf_counter() - t0
        e.incomplete = d
        raise
    d.seconds["total"] = time.perf_counter() - t0
    return d


def model_error(model: MeasuredModel, points, log=print) -> float:
    """The initial model's discretisation error at ``points`` (length unit:
    :func:`refine.solid.floor.discretisation_floor`); 0 with a log line where its split mesh
    cannot be solved."""
    from refine.solid.floor import discretisation_floor

    e = discretisation_floor(model, points)
    if not np.isfinite(e):
        log("  the model's discretisation error is unknown (its mesh split in eight cannot be solved): left out")
        return 0.0
    return e


def focus_for(cfg: EngineConfig, mesh) -> FocusedMesh | None:
    """The graded refit's mesh settings for a body whose model is ``mesh``: ``cfg.focus`` with
    both spacings shrunk alike so that its fine one is at most ``focus_scale`` times the model's
    cell size (:func:`refine.solid.inclusion.cell_size`): never coarser than the model it refines."""
    from refine.solid.inclusion import cell_size
    from refine.solid.inclusion_mesh import coarser

    if cfg.focus is None:
        return None
    k = cfg.focus_scale * cell_size(mesh) / cfg.focus.fine
    return coarser(cfg.focus, k) if k < 1.0 else cfg.focus


def _refine(d: BodyDiagnosis, search: Search, log) -> None:
    """The chosen fit refitted (graded box, errors, profile, discretisation) where it has a region."""
    cfg, best = d.config, d.chosen
    guide, validate, sigma = search.fit, search.hold, search.sigma
    t1 = time.perf_counter()
    focused, region = False, None
    shaped = bool(best.shapes) and hasattr(best.hypothesis, "on")
    focus = focus_for(cfg, best.model.mesh)
    if shaped and focus is not None:
        region = focus_of(best.shapes[0])
        fine_base, g = refit_focused(best, guide, validate, sigma, focus, region=region)
        if g is not None and np.isfinite(g.chi2_fit):
            d.coarse, d.base, best, focused = best, fine_base, g, True
            log(f"  on a graded mesh ({g.model.mesh.n_cells} cells): {g.describe()}")
        d.seconds["focus"] = time.perf_counter() - t1
    best = with_errors(best, guide, sigma)
    if shaped and cfg.profile and getattr(best.hypothesis, "ratio_fitted", True):
        t1 = time.perf_counter()
        best, d.profile, d.starts = profiled(best, guide, validate, sigma, cfg, focused, log)
        d.seconds["profile"] = time.perf_counter() - t1
    d.chosen = best
    if focused and cfg.discretisation and d.profile is not None:
        t1 = time.perf_counter()
        d.discretisation = discretisation_refit(best, guide, validate, sigma, focus, region, cfg.discretisation)
        d.seconds["discretisation"] = time.perf_counter() - t1


def finding_of(d: BodyDiagnosis) -> dict | None:
    """The chosen fit's finding (schema 2), None where nothing was found."""
    if not d.found:
        return None
    f, nu = d.chosen, float(d.base.model.experiment.nu)
    if not f.shapes:  # another material law
        from refine.diagnosis.laws import law_parameters

        params = law_parameters(f)
        return {"kind": "material-law", "cause": f.cause, "centroid": None, "axes": None, "law": f.law,
                "parameters": params, "std": {k: v["std"] for k, v in params.items()}, "details": {}}
    s = f.shapes[0]
    out = {"kind": s.kind, "cause": s.cause, "centroid": list(s.centre), "axes": list(s.axes),
           "directions": [list(c) for c in np.asarray(s.rotation).T], "relative_elasticity": s.ratio,
           "volume": s.volume, "std": ellipsoid_errors(f)}
    det = {"ratio_at_bound": bool(abs(np.log(s.ratio)) > 0.95 * MAX_LOG_RATIO) and s.kind != "cavity",
           "strength": float(strength(s.volume, s.ratio, nu))}
    if d.profile is not None:
        det["profile"] = d.profile.as_dict()
        det["total"] = total_intervals(values_of(s, nu), det["profile"], d.discretisation)
    if d.discretisation is not None:
        det["discretisation"] = d.discretisation.as_dict()
    if d.coarse is not None and d.coarse.shapes:
        c = d.coarse.shapes[0]
        det["coarse_fit"] = {"cells": int(d.coarse.model.mesh.n_cells), "centroid": list(c.centre),
                             "volume": c.volume, "relative_elasticity": c.ratio,
                             "strength": float(strength(c.volume, c.ratio, nu))}
    if d.starts:
        det["fit_start"], det["starts"] = d.starts[-1]["start"], d.starts
    out["details"] = det
    return out


def rows(d: BodyDiagnosis) -> list[dict]:
    """The hypotheses table: the initial model the search compared with, each fit (its kind and
    score: BIC + held-out misfit), each failure (its reason)."""
    fits = [d.search_base or d.base] + d.tried
    out = hypothesis_rows([dataclasses.replace(f, shapes=[]) for f in fits], d.failed)  # its shape rows are 2D
    for r, f in zip(out, fits):
        r["shapes"] = [[float(v) for v in (*s.centre, *s.axes, s.ratio)] for s in f.shapes]  # [c (3), axes (3), ratio]
        r["kinds"] = [s.kind for s in f.shapes]
        r["kind"] = f.shapes[0].kind if f.shapes else ("material-law" if f.cause == "material-law" else "none")
        r["score"] = float(_score(f))
    for r in out[len(fits):]:
        r["kind"] = None
    return out
