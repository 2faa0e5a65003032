"""The chosen hypothesis's final fit (:mod:`refine.diagnosis.pipeline`, step 4): refitted on
every guide point and every frame with standard errors (:func:`_refit_on_every_frame`), and a
very soft region compared with a hole at its outline (:func:`_hole_if_as_likely`)."""

from __future__ import annotations

from refine.diagnosis.config import DiagnoseConfig
from refine.diagnosis.fitted import Fitted, NotApplicable, refit, settle
from refine.diagnosis.holes import fit_hole
from refine.diagnosis.scale import on_frames
from refine.diagnosis.search import Trials
from refine.model.measured import MeasuredModel


def _refit_on_every_frame(chosen: Fitted, search: MeasuredModel, full: MeasuredModel, guide, hold, sigma: float,
                          cfg: DiagnoseConfig) -> Fitted:
    """The chosen hypothesis refitted on every guide point and every frame, with standard errors.
    Its remeshes at the fitted shapes (:func:`~refine.diagnosis.fitted.settle`: one to three
    fits from scratch) run on the search's frames where the search had fewer, and only the
    settled fit is refitted on every frame, from its fitted unknowns (a few steps): a remesh's
    fit on every frame cost a 3,000-point, 11-frame diagnosis most of its refit."""
    if search is full:
        return refit(chosen, guide, hold, sigma, element=cfg.refit_element)
    settled = settle(chosen, guide, hold, sigma, element=cfg.refit_element) or chosen
    return refit(on_frames(settled, full), guide, hold, sigma, element=cfg.refit_element, remesh=settled is chosen)


def _hole_if_as_likely(trials: Trials, soft: Fitted, points) -> Fitted:
    """A softer region refitted to a very low ratio may be a hole: the hole fitted at its
    outline on ``points`` (and remeshed the same way) is chosen if its BIC is as low (it has one
    unknown fewer): a refit on every guide point can take a soft region to ratio 0, a hole in
    all but name. Where points were tracked near the region's middle (material was seen) no
    hole is fitted (:class:`NotApplicable`)."""
    log, region = trials.log, soft.shapes[0]
    try:
        hole = refit(fit_hole(trials.model, region, points, trials.hold, trials.sigma), points, trials.hold,
                     trials.sigma, element=trials.cfg.refit_element)
    except NotApplicable as e:
        log(f"  the soft region (ratio {region.ratio:.2f}) is no hole: {e}")
        return soft
    except Exception as e:  # noqa: BLE001 - a hole that cannot be fitted leaves the soft region chosen
        log(f"  could not fit the soft region (ratio {region.ratio:.2f}) as a hole: {e}")
        return soft
    log(f"  the soft region (ratio {region.ratio:.2f}, BIC {soft.bic:.0f}) as a hole: {hole.describe()}, "
        f"BIC {hole.bic:.0f}")
    return hole if hole.bic <= soft.bic else soft
