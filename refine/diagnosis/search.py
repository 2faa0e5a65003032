"""The diagnosis's search (:mod:`refine.diagnosis.pipeline`, step 3): what every hypothesis is
fitted and judged with (:class:`Trials`), the hypotheses tried greedily from the candidate places
(:func:`_try_hypotheses`, looping the registry's 2D causes, :func:`refine.causes.causes`, fitted
side by side in the diagnosis's pool) and the choice among them (:func:`_choose`, by
:func:`_score`). No cause is named here: a 2D cause is a file of :mod:`refine.causes` whose jobs
see the search at a candidate (:class:`AtCandidate`)."""

from __future__ import annotations

from concurrent.futures import Executor
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from refine.causes.registry import causes
from refine.diagnosis.config import DiagnoseConfig
from refine.diagnosis.fitted import Failed, Fitted, NotApplicable
from refine.diagnosis.localize import Candidate
from refine.diagnosis.noise import NullTest
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

    A ``"global"`` 2D cause's jobs see the search as this (``start`` None).
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


@dataclass(frozen=True)
class AtCandidate:
    """The search at one candidate place, as a ``"place"`` or ``"reshape"`` 2D cause's jobs see it
    (every attribute of :class:`Trials` too: ``model``, ``fit``, ``hold``, ``sigma``, ``cfg``...).

    Attributes:
        trials: the search's :class:`Trials`; candidate: the place tried now;
        used: the candidates of the model so far (empty: this is the first region);
        best: the model so far (the fit that ``used`` gave; None before the first);
        fits: this candidate's fits so far by job name, in the order tried (None: not fitted):
            the place causes' jobs, then each reshape cause's in turn.
    """

    trials: Trials
    candidate: Candidate
    used: tuple
    best: Fitted | None
    fits: dict

    def __getattr__(self, name):
        if name == "trials":  # (not set yet: a copy being made)
            raise AttributeError(name)
        return getattr(self.trials, name)

    def shape(self, ratio: float | None) -> RegionShape:
        """The candidate's ellipse, started at modulus ratio ``ratio`` (None: a hole's)."""
        c = self.candidate
        return RegionShape((float(c.centroid[0]), float(c.centroid[1])), (float(c.axes[0]), float(c.axes[1])),
                           c.angle, "ellipse", ratio)

    def leads(self, f: Fitted) -> bool:
        """Whether ``f`` has the lowest :func:`_score` of this candidate's fits so far."""
        return min((g for g in self.fits.values() if g is not None), key=_score) is f


@dataclass(frozen=True)
class Superseding:
    """A ``"reshape"`` job whose fit supersedes its ``start`` (e.g. a fitted region remeshed at its
    fit): where it fits, it takes the start's place among the candidate's fits (under the start's
    job name) and the start as first fitted leaves the list of fits; its own name adds no entry."""

    job: Callable
    start: Fitted

    def __call__(self) -> Fitted:
        return self.job()


def _failed_cause(cause) -> str:
    """What a failed job of ``cause`` names in the hypotheses table: its first name."""
    return cause.names[0] if cause.names else cause.name


def _try_hypotheses(trials: Trials, candidates: list[Candidate]) -> list[Fitted]:
    """Greedy, from the strongest candidate: every ``"place"`` cause's jobs at it, side by side
    (they start from the candidate alone), then each ``"reshape"`` cause's in turn from each of
    those fits (a reshape cause may read the fits before it, :attr:`AtCandidate.fits`); the
    candidate's best fit (:func:`_score`) is the model so far unless it does not lower the last
    one's BIC by ``bic_margin`` (the search stops); it stops too once the model explains the
    data; a candidate where no cause fits (e.g. none adds to a hole) is passed over. Then, only
    where no model so far explains the data, each ``"global"`` cause in turn (another material
    law, then a hole in the law that fitted best), its jobs side by side. A hypothesis whose building, start, fit or remesh raises
    is a row of ``trials.failed`` (its reason; its cause its registry cause's first name) and the
    search goes on without it; one the data rule out
    (:class:`~refine.diagnosis.fitted.NotApplicable`) is logged only."""
    out, cfg, log = trials.fitted, trials.cfg, trials.log

    def attempt(cause, name, job):
        try:
            f = job()
            log(f"  tried {f.describe()}")
            return f
        except NotApplicable as e:
            log(f"  not tried: {e}")
            return None
        except Exception as e:  # noqa: BLE001 - a hypothesis that cannot be fitted is a row with its reason
            trials.failed.append(Failed.of(name, _failed_cause(cause), e))
            log(f"  could not fit {name}: {type(e).__name__}: {e}")
            return None

    def jobs_of(cause, search, starts) -> dict:
        """``cause``'s jobs from each of ``starts`` (name: (cause, job)); none where its
        ``applies`` says why not (logged); a cause whose jobs raise is a row with its reason."""
        why = cause.applies(search)
        if why:
            log(f"  {cause.name} not tried: {why}")
            return {}
        jobs = {}
        for start in starts:
            try:
                jobs.update({name: (cause, job) for name, job in (cause.jobs(search, start) or {}).items()})
            except Exception as e:  # noqa: BLE001 - a cause that cannot say its jobs is a row too
                trials.failed.append(Failed.of(cause.name, _failed_cause(cause), e))
                log(f"  could not start {cause.name}: {type(e).__name__}: {e}")
        return jobs

    def side_by_side(jobs: dict) -> dict:
        """Fit the jobs (name: (cause, a function of nothing)) in the pool; their fits by name (None: not fitted)."""
        futures = {name: trials.pool.submit(attempt, cause, name, job) for name, (cause, job) in jobs.items()}
        fits = {name: f.result() for name, f in futures.items()}
        out.extend(f for f in fits.values() if f is not None)
        return fits

    best, used = None, ()
    for c in candidates:
        at = AtCandidate(trials, c, used, best, {})
        at.fits.update(side_by_side({k: v for cause in causes(2, "place") for k, v in jobs_of(cause, at, [c]).items()}))
        placed = [f for f in at.fits.values() if f is not None]
        for cause in causes(2, "reshape"):
            jobs = jobs_of(cause, at, placed)
            for name, f in side_by_side(jobs).items():
                job = jobs[name][1]
                if not isinstance(job, Superseding):
                    at.fits[name] = f
                elif f is not None:  # the start as first fitted is superseded (listed once, also when kept)
                    at.fits[next(k for k, g in at.fits.items() if g is job.start)] = f
                    out.remove(job.start)
        fits = [f for f in at.fits.values() if f is not None]
        if not fits:
            continue
        top = min(fits, key=_score)
        if best is not None and top.bic > best.bic - cfg.bic_margin:
            break  # the extra region does not pay for its parameters
        best, used = top, (*used, c)
        if trials.explains(best):
            break
    if best is None or not trials.explains(best):
        for cause in causes(2, "global"):
            side_by_side(jobs_of(cause, trials, [None]))
    return out


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
