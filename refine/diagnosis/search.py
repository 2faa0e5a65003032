"""The diagnosis's search (:mod:`refine.diagnosis.pipeline`, step 3): what every hypothesis is
fitted and judged with (:class:`Trials`), the hypotheses tried greedily from the candidate regions
(:func:`_try_hypotheses`: regions, holes, rectangles, other material laws, fitted side by side in
the diagnosis's pool) and the choice among them (:func:`_choose`, by :func:`_score`)."""

from __future__ import annotations

from concurrent.futures import Executor
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from refine.diagnosis.config import DiagnoseConfig
from refine.diagnosis.fitted import Failed, Fitted, NotApplicable
from refine.diagnosis.holes import fit_hole
from refine.diagnosis.hole_law import hole_law_jobs
from refine.diagnosis.laws import ALTERNATIVE_LAWS, fit_law
from refine.diagnosis.localize import Candidate
from refine.diagnosis.noise import NullTest
from refine.diagnosis.regions import fit_rectangle, fit_regions, refit_ellipse
from refine.diagnosis.shapes import RegionShape
from refine.model.measured import MeasuredModel


@dataclass(frozen=True)
class Trials:
    """What every hypothesis of one diagnosis is fitted and judged with.

    Attributes:
        model: the initial model; fit, hold: ``(n_points,)`` masks of the fitting and held-out
        guide points; sigma: the noise the residuals are weighted with (noise and model error);
        cfg: the settings; null: the initial model's null test; n_fit: residuals on the fitting
        points; log: where progress lines go; pool: the threads that fit hypotheses side by side;
        failed: the hypotheses that could not be fitted (:class:`~refine.diagnosis.fitted.Failed`,
        appended by the search: rows of the report's hypotheses table with their reasons);
        fitted: the hypotheses fitted so far (what :func:`_try_hypotheses` returns, kept here too
        so that a search cut short still has them).
    """

    model: MeasuredModel
    fit: np.ndarray
    hold: np.ndarray
    sigma: float
    cfg: DiagnoseConfig
    null: NullTest
    n_fit: int
    log: Callable[[str], None]
    pool: Executor
    failed: list = field(default_factory=list)
    fitted: list = field(default_factory=list)

    def explains(self, f: Fitted) -> bool:
        """Whether a fit leaves no more misfit than noise, its propagation and model error would."""
        return f.chi2_fit / max(self.n_fit, 1) < 1.5 * (1.0 + self.null.propagation)


def _shape_of(c: Candidate, ratio: float) -> RegionShape:
    """A candidate's ellipse, started at ``ratio``."""
    return RegionShape((float(c.centroid[0]), float(c.centroid[1])), (float(c.axes[0]), float(c.axes[1])), c.angle,
                       "ellipse", ratio)


def _try_hypotheses(trials: Trials, candidates: list[Candidate]) -> list[Fitted]:
    """Greedy: the strongest candidate region first (as a stiffer/softer region, and as a hole
    when softer, the two fitted side by side); add the next candidate only while the misfit is
    still above the null level; other material laws (side by side) only if no region explains
    the data, then the best hole in the law that fitted best (:func:`hole_law_jobs`). A hypothesis
    whose building, start, fit or remesh raises is recorded in ``trials.failed`` (its reason) and
    the search goes on without it."""
    out = trials.fitted
    model, fit, hold, sigma, cfg, log = trials.model, trials.fit, trials.hold, trials.sigma, trials.cfg, trials.log

    def attempt(name, job):
        try:
            f = job()
            log(f"  tried {f.describe()}")
            return f
        except NotApplicable as e:
            log(f"  not tried: {e}")
            return None
        except Exception as e:  # noqa: BLE001 - a hypothesis that cannot be fitted is a row with its reason
            trials.failed.append(Failed.of(name, _cause_of_job(name), e))
            log(f"  could not fit {name}: {type(e).__name__}: {e}")
            return None

    def side_by_side(**jobs):
        """Fit the jobs (name: a function of nothing) in the pool; their fits by name (None: not fitted)."""
        futures = {name: trials.pool.submit(attempt, name, job) for name, job in jobs.items()}
        fits = {name: f.result() for name, f in futures.items()}
        out.extend(f for f in fits.values() if f is not None)
        return fits

    best = None
    used: list[Candidate] = []
    for c in candidates:
        trial = used + [c]
        # the first region starts x3 or /3 at its candidate's outline; later ones start where the
        # last fit left the others, the new one at x1.5 or /1.5, so the extended model starts
        # close to the last one (a start at /3 could send a spurious second region's fit astray)
        shapes = [*(best.shapes if used else ()), _shape_of(c, (1.5 if used else 3.0) ** c.sign)]
        signs = [k.sign for k in trial]
        jobs = {"ellipse": lambda: fit_regions(model, shapes, signs, fit, hold, sigma, restarts=())}
        if c.sign < 0 and not used:
            jobs["hole"] = lambda: fit_hole(model, _shape_of(c, None), fit, hold, sigma)
        fits = side_by_side(**jobs)
        soft, hole = fits.get("ellipse"), fits.get("hole")
        # A very soft region may be a hole whose fit from the candidate's rough outline settled
        # badly: try the hole again from the soft region's fitted outline, unless the first
        # hole fit was far off (over twice the soft region's misfit: the outline is not it).
        if ("hole" in jobs and soft is not None and soft.cause == "softer-region"
                and soft.shapes[0].ratio < cfg.hole_below
                and (hole is None or (soft.bic < hole.bic and hole.chi2_fit < 2.0 * soft.chi2_fit))):
            fits.update(side_by_side(**{"hole from region": lambda: fit_hole(model, soft.shapes[0], fit, hold, sigma)}))
        region = fits.get("ellipse")
        if (not used and region is not None  # one region: never "regions"
                and _rectangles_wanted(region, model, cfg, trials.explains(region))
                and min((f for f in fits.values() if f is not None), key=_score) is region):
            # the region as a rectangle, from the fitted ellipse, turned 0 and pi/4 from it, beside
            # the ellipse remeshed at its fit (each rectangle is remeshed at its fit too)
            more = side_by_side(
                **{"rectangle": lambda: fit_rectangle(model, region, 0.0, fit, hold, sigma),
                   "rectangle turned": lambda: fit_rectangle(model, region, np.pi / 4, fit, hold, sigma),
                   "ellipse remeshed": lambda: refit_ellipse(region, fit, hold)})
            fits.update(rectangle=more["rectangle"], **{"rectangle turned": more["rectangle turned"]})
            if more["ellipse remeshed"] is not None:  # the ellipse as first fitted is superseded by its remeshed fit
                fits["ellipse"] = more["ellipse remeshed"]
                out.remove(region)  # (listed once, also when the remesh kept it)
        fits = [f for f in fits.values() if f is not None]
        if not fits:
            continue
        top = min(fits, key=_score)
        if best is not None and top.bic > best.bic - cfg.bic_margin:
            break  # the extra region does not pay for its parameters
        best, used = top, trial
        if trials.explains(best) or best.cause == "hole":
            break
    if cfg.try_laws and (best is None or not trials.explains(best)):
        side_by_side(**{law: (lambda law=law: fit_law(model, law, fit, hold, sigma))
                        for law in ALTERNATIVE_LAWS.get(model.experiment.law, ())})
        side_by_side(**hole_law_jobs(model, out, fit, hold, sigma))  # a hole in the law that fitted best
    return out


def _cause_of_job(name: str) -> str:
    """What a search job (by its name in :func:`_try_hypotheses`) would have named: a hole, a
    material law (a law's name), a hole in another law, or a region."""
    if name.startswith("hole"):  # "hole", "hole from region", "hole with LAW"
        return "hole"
    if name in {law for laws in ALTERNATIVE_LAWS.values() for law in laws}:
        return "material-law"
    return "region"


def _rectangles_wanted(region: Fitted, model, cfg: DiagnoseConfig, explained: bool = False) -> bool:
    """Whether to fit ``region`` (one fitted ellipse) as a rectangle too: as
    ``cfg.try_rectangles`` says, or, when it is None, where the ellipse leaves a misfit the noise
    does not explain (``explained`` False) and its smaller semi-axis spans
    ``cfg.rectangle_spacings`` grid spacings (fewer tracked points along a side cannot tell a
    corner from a curve)."""
    if cfg.try_rectangles is not None:
        return bool(cfg.try_rectangles)
    return not explained and min(region.shapes[0].axes) >= cfg.rectangle_spacings * model.spacing


def _score(f: Fitted) -> float:
    """BIC on the fitting points plus the misfit on the held-out ones: the information criterion
    and the held-out evidence in one number (-2 log-likelihood of the held-out points, which no
    fit saw, under the fitted model). It decides between hypotheses that BIC alone puts close,
    such as a very soft region and a hole of the same outline (one parameter apart)."""
    return f.bic + f.chi2_holdout


def _choose(base: Fitted, tried: list[Fitted], cfg: DiagnoseConfig) -> Fitted:
    """The lowest :func:`_score` among hypotheses that beat the initial model's BIC by
    ``bic_margin`` and also lower the held-out misfit; the initial model if none does."""
    good = [f for f in tried[1:] if f.bic < base.bic - cfg.bic_margin and f.chi2_holdout < base.chi2_holdout]
    return min(good, key=_score) if good else base
