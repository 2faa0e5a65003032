"""The discretisation term on a real fit (refine.diagnosis.uncertainty.with_discretisation): on
noise-free data from the finer quadratic solve of a larger sheet hiding a stiffer ellipse drawn
under a seed, the fitted ratio's error is of the size the mesh's and the drive's Richardson
estimates give, and the finding reports them. Slow (three fits of a small sheet with their
compilations); benchmarks/error_coverage.py measures the coverage over many cases."""

import numpy as np
import pytest


@pytest.mark.slow
def test_the_discretisation_estimate_is_the_size_of_the_noise_free_error():
    from tests._ellipse_fit import fitted_ellipse

    from refine.diagnosis.findings import findings
    from refine.diagnosis.uncertainty import with_discretisation

    sigma = 1e-3
    f, guide, hold, ratio = fitted_ellipse(41, noise=0.0, sigma=sigma)
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
