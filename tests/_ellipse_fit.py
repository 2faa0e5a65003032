"""A fitted stiffer ellipse for the discretisation-error tests: a small sheet hiding an ellipse of
random place, size and ratio (drawn under ``seed``), data from the finer quadratic solve of a
larger sheet with ``noise`` (mm), the ellipse fitted from the truth and refitted on quadratic
triangles. Shared by tests/test_error_bars_fit.py and tests/test_diagnose_speed.py."""

from __future__ import annotations

import numpy as np

import jaxfem as jf


def fitted_ellipse(seed: int, noise: float, sigma: float):
    """(the refitted ``Fitted``, the guide mask, the hold-out mask, the true ratio) of the case
    drawn under ``seed``; ``sigma``: the noise level the fit assumes (mm)."""
    from refine.diagnosis.fitted import fit, refit
    from refine.diagnosis.regions import regions_hypothesis
    from refine.diagnosis.shapes import RegionShape
    from refine.model.measured import MeasuredModel
    from refine.demo_data import Inclusion, Truth, synthetic_bundle

    rng = np.random.default_rng(seed)
    cx, cy, angle = rng.uniform(17, 23), rng.uniform(13, 17), rng.uniform(0, 3)
    a, b = rng.uniform(3.5, 4.5), rng.uniform(2.5, 3.5)
    ratio = float(rng.uniform(3, 6))
    truth = Truth(inclusions=(Inclusion(jf.Ellipse(cx, cy, a, b, angle), ratio),))
    bundle = synthetic_bundle(truth, seed=seed, roi=(5.0, 5.0, 35.0, 25.0), sheet=(0.0, 0.0, 40.0, 30.0),
                              spacing=2.5, noise=noise, fractions=(1.0,), h=1.0)
    obs = bundle.observations
    guide, hold = obs.mask("guide"), obs.mask("validate")
    model = MeasuredModel(bundle.experiment, obs)
    start = RegionShape((cx, cy), (a, b), angle, "ellipse", ratio)
    f = refit(fit(regions_hypothesis(model, [start], [1]), guide, hold, sigma), guide, hold, sigma, element="tri6")
    return f, guide, hold, ratio
