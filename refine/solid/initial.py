"""The initial model of a solid diagnosis and its null test: the model without an effect fitted
on the guide points, refused where its solve fails, and its misfit tested against the noise with
the boundary points' noise carried through the model (:func:`refine.diagnosis.noise.null_test`).
Shared by the cup holder's and the block's diagnoses (the cup holder's default null test weighs the
global model instead: :mod:`refine.solid.null_level`)."""

from __future__ import annotations

import numpy as np

from refine.diagnosis.fitted import Fitted, baseline
from refine.diagnosis.noise import NullTest, null_test, propagated_noise
from refine.measures import Residuals


def checked_baseline(model, obs, sigma: float, samples: int = 8, sigma_model: float = 0.0,
                     fit_sigma: float | None = None) -> tuple[Fitted, NullTest]:
    """The initial model ``model`` (a :class:`refine.model.MeasuredModel` of the observations
    ``obs``) on their guide points, held-out errors on its validate points, and the null test of
    its guide misfit at the noise ``sigma`` (length unit) with ``samples`` noisy copies of the drive
    (:func:`initial_null`), ``sigma_model`` the model's own discretisation error (length unit) in
    its null level; the fit's misfit weighed at ``fit_sigma`` (None: ``sigma``). Raises the
    model's solve failure (naming where Newton stopped) where the initial model cannot be solved."""
    base = initial_fit(model, obs, sigma if fit_sigma is None else fit_sigma)
    return base, initial_null(base, obs, sigma, samples, sigma_model)


def initial_fit(model, obs, sigma: float) -> Fitted:
    """The initial model on the guide points of ``obs``, scored on its validate points (noise
    ``sigma``, length unit); raises the model's solve failure where it cannot be solved."""
    guide, validate = obs.roles == "guide", obs.roles == "validate"
    base = baseline(model, guide, validate, sigma)
    if not np.isfinite(base.chi2_fit):
        model.raise_solve_failure(model.params())
    return base


def initial_null(base: Fitted, obs, sigma: float, samples: int = 8, sigma_model: float = 0.0) -> NullTest:
    """The null test of the initial fit ``base``'s guide misfit against the noise ``sigma``
    (length unit), the model's discretisation error ``sigma_model`` (length unit) and ``samples``
    noisy copies of the drive carried through the model."""
    guide = obs.roles == "guide"
    at = Residuals.at(obs.displacements, guide, sigma)
    model = base.model
    return null_test(at.difference(base.predicted), at.valid, sigma, sigma_model,
                     propagated_noise(model, model.params(), sigma, guide, samples=samples))
