"""The discretisation term on a real fit (refine.diagnosis.uncertainty.with_discretisation): on
noise-free data from the finer quadratic solve of a larger sheet hiding a stiffer ellipse drawn
under a seed, the fitted ratio's error is of the size the mesh's and the drive's Richardson
estimates give, and the finding reports them. Slow (three fits of a small sheet with their
compilations); benchmarks/error_coverage.py measures the coverage over many cases."""

import numpy as np
import pytest

import jaxfem as jf


@pytest.mark.slow
def test_the_discretisation_estimate_is_the_size_of_the_noise_free_error():
    from refine.diagnosis.findings import findings
    from refine.diagnosis.fitted import fit, refit
    from refine.diagnosis.regions import regions_hypothesis
    from refine.diagnosis.shapes import RegionShape
    from refine.diagnosis.uncertainty import with_discretisation
    from refine.model.measured import MeasuredModel
    from refine.synthetic.sheet import Inclusion, Truth, synthetic_bundle

    rng = np.random.default_rng(41)
    cx, cy, angle = rng.uniform(17, 23), rng.uniform(13, 17), rng.uniform(0, 3)
    a, b = rng.uniform(3.5, 4.5), rng.uniform(2.5, 3.5)
    ratio = float(rng.uniform(3, 6))
    truth = Truth(inclusions=(Inclusion(jf.Ellipse(cx, cy, a, b, angle), ratio),))
    bundle = synthetic_bundle(truth, seed=41, roi=(5.0, 5.0, 35.0, 25.0), sheet=(0.0, 0.0, 40.0, 30.0), spacing=2.5,
                              noise=0.0, fractions=(1.0,), h=1.0)
    obs = bundle.observations
    guide, hold = obs.mask("guide"), obs.mask("validate")
    model = MeasuredModel(bundle.experiment, obs)
    sigma = 1e-3
    start = RegionShape((cx, cy), (a, b), angle, "ellipse", ratio)
    f = refit(fit(regions_hypothesis(model, [start], [1]), guide, hold, sigma), guide, hold, sigma, element="tri6")
    g = with_discretisation(f, guide, hold, sigma)
    assert set(g.q_disc_parts) == {"mesh", "drive"}
    assert np.allclose(g.q_disc, np.hypot(g.q_disc_parts["mesh"], g.q_disc_parts["drive"]), equal_nan=True)
    error = abs(g.shapes[0].ratio - ratio)
    estimate = g.q_disc[0, 6]
    assert np.isfinite(estimate) and estimate > 0
    # the truth within 2 estimated errors (noise-free: nothing else to cover it), and the estimate
    # not a blanket: under 10 times the error and 1 % of the ratio
    assert error <= 2 * estimate + 1e-4 * ratio, (error, g.q_disc_parts)
    assert estimate <= max(10 * error, 0.01 * ratio), (error, g.q_disc_parts)
    [finding] = findings(g, "evidence", None)
    j = finding.to_json()
    assert j["discretisation_parts"]["drive"]["relative_elasticity"] == pytest.approx(
        g.q_disc_parts["drive"][0, 6], abs=1e-4)
    parts = (j["relative_elasticity_std"], j["discretisation"]["relative_elasticity"])
    assert j["relative_elasticity_total_std"] == pytest.approx(np.hypot(*parts), abs=2e-4)
