"""The initial model of a solid diagnosis and its null test: the model without an effect fitted
on the guide points, refused where its solve fails, and its misfit tested against the noise with
the boundary points' noise carried through the model (:func:`refine.diagnosis.noise.null_test`).
Shared by the cup holder's and the block's diagnoses."""

from __future__ import annotations

import numpy as np

from refine.diagnosis.fitted import Fitted, baseline
from refine.diagnosis.noise import NullTest, null_test, propagated_noise
from refine.measures import Residuals


def checked_baseline(model, obs, sigma: float, samples: int = 8) -> tuple[Fitted, NullTest]:
    """The initial model ``model`` (a :class:`refine.model.MeasuredModel` of the observations
    ``obs``) on their guide points,
    held-out errors on its validate points, and the null test of its guide misfit at the noise
    ``sigma`` (length unit) with ``samples`` noisy copies of the drive. Raises the model's solve
    failure (naming where Newton stopped) where the initial model cannot be solved."""
    guide, validate = obs.roles == "guide", obs.roles == "validate"
    base = baseline(model, guide, validate, sigma)
    if not np.isfinite(base.chi2_fit):
        model.raise_solve_failure(model.params())
    at = Residuals.at(obs.displacements, guide, sigma)
    null = null_test(at.difference(base.predicted), at.valid, sigma, 0.0,
                     propagated_noise(model, model.params(), sigma, guide, samples=samples))
    return base, null
