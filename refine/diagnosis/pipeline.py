"""Diagnosis: show what the initial model gets wrong, decide whether anything is wrong at all,
name the cause, extend the model, and measure the gain on held-out points.

0. Scale: the models' mesh size follows the domain (at most ``max_cells`` cells), and the search
   (steps 2 and 3) runs on the frames of most motion (:mod:`refine.diagnosis.scale`), so that a
   diagnosis costs about the same for 300 or 3,000 points, 2 or 20 frames; the initial model on
   every frame reuses the search's compiled solve (no program of its own: compiling is most of a
   diagnosis's cost).
1. Show: drive the initial (uniform) model with the boundary points; residuals at guide points
   and the strain map.
2. Decide: compare the misfit with its null level (noise, its propagation from the driving
   points, the model's discretisation error); a homogeneous sample gives no finding.
3. Name: candidate places come from gaps in the tracked points inside the domain (a hole has no
   material points), from a regularised modulus field fitted by adjoint gradients and from the
   measured strain map's departures from the model's (:mod:`refine.diagnosis.candidates`);
   stiffer/softer regions, holes and other material laws are fitted by exact gradients and
   compared by BIC plus their misfit on held-out guide points, never by training error alone;
   a hole is not tried where tracked points lie near the candidate's middle.
4. Extend and measure: the chosen model is refitted on all guide points and every frame,
   remeshed at its fitted shapes with quadratic triangles (linear ones bias a strained soft
   region's modulus low); a softer region whose stiffness is indistinguishable from zero and
   that holds no tracked point is named a hole; validation points, held out of every fit,
   measure the gain.

An error or an interrupt after the initial model leaves with what was done attached
(``exception.incomplete``, :mod:`refine.diagnosis.incomplete`: the rows so far, the stage, the
error), which ``nonrigid diagnose`` writes before it exits non-zero.
"""

from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace

import numpy as np

from jaxfem.cache import compile_counts, compiles_since

from refine.bundle.io import Bundle
from refine.measures import Residuals, mean_position_error, tracking_error
from refine.diagnosis.forces import ForceScale, force_scale
from refine.diagnosis.config import DiagnoseConfig
from refine.diagnosis.findings import Finding, findings
from refine.diagnosis.fitted import Fitted, baseline, hypothesis_rows
from refine.diagnosis.uncertainty import with_discretisation
from refine.diagnosis.discretisation import discretisation_floor
from refine.diagnosis.candidates import data_candidates
from refine.diagnosis.holes import named_hole
from refine.diagnosis.restarts import CHOSEN_RESTARTS, best_of_restarts
from refine.diagnosis.localize import fit_field
from refine.diagnosis.scale import at_frames, drives_alike, every_frame, mesh_size, search_frames
from refine.model.measured import MeasuredModel, grid_spacing
from refine.diagnosis.noise import NullTest, estimate_noise, null_test, propagated_noise
from refine.diagnosis.provenance import provenance
from refine.diagnosis.search import Trials, _choose, _try_hypotheses
from refine.diagnosis.final_fit import _hole_if_as_likely, _refit_on_every_frame
from refine.diagnosis.incomplete import Incomplete


#: the search model is padded as for a mesh this many times larger: the hypotheses' meshes (larger,
#: they follow the shapes) then reuse its compiled Newton instead of their own bucket's (jaxfem.program)
SEARCH_HEADROOM = 1.25


@dataclass
class Diagnosis:
    """Everything a diagnosis found; :meth:`report` gives the report.json content."""

    bundle: Bundle
    null: NullTest
    baseline: Fitted
    chosen: Fitted
    tried: list
    candidates: list
    field: np.ndarray | None
    model: MeasuredModel
    errors: dict = field(default_factory=dict)
    seconds: float = 0.0
    force: ForceScale | None = None
    config: DiagnoseConfig = field(default_factory=DiagnoseConfig)
    selected: Fitted | None = None  # the chosen hypothesis as fitted and scored beside the others (before its refit)
    search_frames: tuple = ()
    failed: list = field(default_factory=list)  # hypotheses that could not be fitted (fitted.Failed)
    compiles: dict = field(default_factory=dict)  # the programs compiled meanwhile (jaxfem.compiles_since)

    @property
    def absolute(self) -> bool:
        """Whether measured forces made the moduli absolute."""
        return self.force is not None

    @property
    def background_modulus(self) -> float | None:
        """The background's absolute modulus (stress units, for the assumed thickness), or None."""
        return None if self.force is None else float(self.bundle.experiment.E * self.force.scale)

    @property
    def findings(self) -> list[Finding]:
        """What was found, one :class:`Finding` per cause (none when the initial model stands)."""
        return findings(self.chosen, self._evidence(), self.background_modulus if self.absolute else None)

    def _evidence(self) -> str:
        # the numbers of the hypotheses' table (report.json's decision): the baseline and the chosen
        # hypothesis scored on the same fitting and held-out points, before the chosen one's refit on
        # every guide point (whose misfit sums over more points and is not comparable)
        b, c = self.baseline, self.selected or self.chosen
        refit = f"; refitted on every guide point as {self.chosen.cause}" if self.chosen.cause != c.cause else ""
        return (f"initial model misfit {self.null.ratio:.1f}x its null level (p = {self.null.p_value:.2g}); "
                f"{c.cause} lowers BIC from {b.bic:.0f} to {c.bic:.0f} (by {b.bic - c.bic:.0f}) and the held-out "
                f"guide misfit from {b.chi2_holdout:.0f} to {c.chi2_holdout:.0f}{refit}")

    def _modulus_note(self) -> str:
        ex = self.bundle.experiment
        if not self.absolute:
            what = "E x thickness" if ex.kind == "plane-stress" else "modulus"
            return f"moduli are relative (no measured forces): only {what} ratios are identifiable"
        f = self.force
        return (f"moduli are absolute: the force measured on the {', '.join(f.edges)} side fixes E x thickness; "
                f"they assume the thickness {ex.thickness or 1.0:g} (one factor on every modulus explains the "
                f"measured forces to {100 * f.relative_residual:.1f} %)")

    def report(self) -> dict:
        e = self.errors
        return {"bundle": self.bundle.experiment.name,
                "background": {"modulus": None if not self.absolute else round(self.background_modulus, 4),
                               "relative_elasticity": 1.0},
                "baseline": e["baseline"], "findings": [f.to_json() for f in self.findings], "refined": e["refined"],
                "gain": {"validation_error": e["gain"]},
                "decision": {"null_statistic": self.null.statistic, "dof": self.null.dof,
                             "p_value": self.null.p_value, "noise_std": self.null.sigma,
                             "model_error_std": self.null.sigma_model,
                             "hypotheses": hypothesis_rows(self.tried, self.failed),
                             "candidates": [{"source": c.source, "sign": c.sign,
                                             "centroid": [round(float(v), 4) for v in c.centroid],
                                             "axes": [round(float(v), 4) for v in c.axes]} for c in self.candidates],
                             "search_frames": [int(f) + 1 for f in self.search_frames]},
                "note": self._modulus_note(),
                "seconds": round(self.seconds, 2),
                "provenance": provenance(self)}


def _errors(obs, pred) -> dict:
    out = {}
    for role, key in (("guide", "guide_error"), ("validate", "validation_error")):
        m = obs.mask(role)
        out[key] = mean_position_error(pred[:, m], obs.displacements[:, m]).value if m.any() else None
    m = obs.mask("validate")
    out["tracking_error"] = tracking_error(pred[:, m], obs.displacements[:, m]).value if m.any() else None
    return out


def diagnose(bundle: Bundle, config: DiagnoseConfig | None = None, log=print) -> Diagnosis:
    """Diagnose a measurement bundle (see the module docstring)."""
    cfg = config or DiagnoseConfig()
    t0, compiles0 = time.perf_counter(), compile_counts()
    say = log
    log = lambda msg: say(f"[{time.perf_counter() - t0:6.1f} s] {msg}")  # noqa: E731
    ex, obs = bundle.experiment, bundle.observations
    h = cfg.h if cfg.h is not None else mesh_size(ex.domain, grid_spacing(obs.reference), cfg.max_cells)
    full = MeasuredModel(ex, obs, root=bundle.root, h=h, linear_solver=cfg.linear_solver, headroom=SEARCH_HEADROOM)
    frames = search_frames(obs, cfg.search_frames)
    model = full if len(frames) == obs.n_frames else MeasuredModel(ex, at_frames(obs, frames), mesh=full.mesh, h=full.h,
                                                                   linear_solver=cfg.linear_solver,
                                                                   headroom=SEARCH_HEADROOM)
    log(f"{obs.n_points} points x {obs.n_frames} frames; mesh of {full.mesh.n_cells} cells (size {full.h:.3g}); "
        f"search on frame{'s' if len(frames) > 1 else ''} {', '.join(str(f + 1) for f in frames)}")
    guide = obs.mask("guide")
    rng = np.random.default_rng(cfg.seed)
    gidx = np.flatnonzero(guide)
    hold = np.zeros(obs.n_points, bool)
    hold[rng.choice(gidx, max(1, int(round(cfg.holdout_fraction * len(gidx)))), replace=False)] = True
    fit = guide & ~hold

    pool = ThreadPoolExecutor(max(1, cfg.workers))
    floor = pool.submit(discretisation_floor, model, guide)  # a finer model, compiled beside the initial one
    # the initial model on every frame: from the search model's compiled solve where every frame
    # is driven alike (no program of its own), else compiled beside the search's set-up
    alike = drives_alike(model, full)
    full_compiled = pool.submit(full.predict, full.params()) if model is not full and not alike else None
    if not np.isfinite(np.asarray(model.predict(model.params()))).all():
        pool.shutdown(cancel_futures=True)
        model.raise_solve_failure(model.params())  # e.g. boundary motion that folds the sheet: no fit can help
    sigma = ex.noise_std if ex.noise_std is not None else estimate_noise(obs)
    V = propagated_noise(model, model.params(), sigma, guide, seed=cfg.seed) if sigma > 0 else np.zeros((0,))
    sigma_model = floor.result()  # (the noise's propagation above ran beside it)
    sigma_eff = float(np.sqrt(sigma**2 + sigma_model**2)) or 1.0
    log(f"noise {sigma:.3g} ({'given' if ex.noise_std is not None else 'estimated'}), model discretisation "
        f"error {sigma_model:.3g}")
    base = baseline(model, fit, hold, sigma_eff)
    at_guide = Residuals.at(model.obs.displacements, guide)
    shape = at_guide.measured.shape
    null = null_test(at_guide.difference(base.predicted), at_guide.valid, sigma, sigma_model,
                     V.reshape((-1,) + shape) if V.size else np.zeros((0,) + shape))
    log(f"initial model: misfit {null.ratio:.2f}x its null level over {null.dof} residuals (p = {null.p_value:.3g})")
    tried, candidates, z, selected, trials = [base], [], None, None, None
    chosen, stage = base, "the localisation field"
    try:
        if null.p_value < cfg.alpha:
            n_res = Residuals.at(model.obs.displacements, fit).n
            z, _ = fit_field(model, weight=cfg.field_weight * n_res / model.mesh.n_cells, sigma=sigma_eff, points=fit)
            stage = "the candidate regions"
            candidates = data_candidates(model, z, base.predicted, fit, sigma, cfg)
            log(f"{len(candidates)} candidate regions: " +
                ", ".join(f"{'stiffer' if c.sign > 0 else 'softer'} at ({c.centroid[0]:.1f}, {c.centroid[1]:.1f}) "
                          f"from the {c.source}" for c in candidates))
            stage = "the search"
            trials = Trials(model, fit, hold, sigma_eff, cfg, null, n_res, log, pool)
            tried += _try_hypotheses(trials, candidates)
            chosen = selected = _choose(base, tried, cfg)
            if chosen.cause in ("stiffer-region", "softer-region", "regions"):  # the search fits once; the chosen
                stage = "the chosen region's restarts"
                chosen = best_of_restarts(chosen, chosen.shapes, fit, hold, CHOSEN_RESTARTS, pool)  # and its valley
            if chosen is not base:  # refit the chosen model on every guide point and every frame
                log(f"refit on every frame: {chosen.describe()}")
                stage = "the refit on every frame"
                chosen = _refit_on_every_frame(chosen, model, full, guide, hold, sigma_eff, cfg)
                if chosen.cause == "softer-region" and chosen.shapes[0].ratio < cfg.hole_refit_below:
                    stage = "the comparison with a hole"
                    chosen = _hole_if_as_likely(replace(trials, model=full), chosen, guide)
                chosen = named_hole(chosen, obs.reference, cfg.hole_refit_below)
                if cfg.discretisation_error:  # the mesh's and the drive's share of the error bars: two more fits
                    t = time.perf_counter()
                    stage = "the discretisation error"
                    log(f"refitted: {chosen.describe()}; its discretisation error: a coarser mesh, a sparser drive")
                    chosen = with_discretisation(chosen, guide, hold, sigma_eff, pool=pool)
                    log(f"discretisation error estimated ({time.perf_counter() - t:.0f} s)")
        stage = "the initial model on every frame"
        if model is not full:
            pred = full_compiled.result() if full_compiled is not None else every_frame(model, full, model.params())
            base = baseline(full, fit, hold, sigma_eff, predicted=pred)
        chosen = base if chosen is tried[0] else chosen
        pool.shutdown()
        log(f"chosen: {chosen.describe()}")
        stage = "the errors and forces"
        d = Diagnosis(bundle, null, base, chosen, tried, candidates, z, model, seconds=0.0, config=cfg,
                      selected=selected, search_frames=frames, failed=trials.failed if trials is not None else [])
        eb, er = _errors(obs, base.predicted), _errors(obs, chosen.predicted)
        gain = (eb["validation_error"] / er["validation_error"]) if er.get("validation_error") else None
        d.errors = {"baseline": eb, "refined": er, "gain": gain}
        if obs.forces is not None:
            d.force = force_scale(chosen.model, chosen.theta)
            if d.force is not None:
                log(f"forces: background modulus {d.background_modulus:.4g} (the force is matched to "
                    f"{100 * d.force.relative_residual:.1f} %)")
        d.seconds, d.compiles = time.perf_counter() - t0, compiles_since(compiles0)
        return d
    except BaseException as e:  # incl. KeyboardInterrupt: what was done goes with it (diagnosis.incomplete)
        pool.shutdown(wait=False, cancel_futures=True)
        fitted = tried if len(tried) > 1 or trials is None else tried + list(trials.fitted)
        e.incomplete = Incomplete(bundle, cfg, null, tried[0], fitted, [] if trials is None else list(trials.failed),
                                  candidates, stage, e, time.perf_counter() - t0, model)
        log(f"stopped in {stage}: {type(e).__name__}: {e}")
        raise
