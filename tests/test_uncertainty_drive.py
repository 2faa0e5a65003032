"""The drive's share of the standard errors (refine.diagnosis.uncertainty.drive_covariance): noise on
the boundary points that drive the model moves the fitted unknowns by ``-M dB`` to first order;
checked against Gauss-Newton steps from the converged fit on perturbed drives, on a small
sheet hiding a stiffer ellipse drawn under a seed (data from the finer quadratic solve)."""

import numpy as np
import pytest

import jaxfem as jf


@pytest.mark.slow  # small compilations, but 15 min at load 30-55 on the shared 2 cores; benchmarks/error_coverage.py measures the effect
def test_drive_covariance_is_the_first_order_motion_of_the_fit_under_drive_noise():
    from refine.diagnosis.fitted import fit
    from refine.diagnosis.regions import regions_hypothesis
    from refine.diagnosis.shapes import RegionShape
    from refine.diagnosis.uncertainty import drive_covariance, drive_sensitivity
    from refine.measures import Residuals
    from refine.model.measured import MeasuredModel
    from refine.demo_data import Inclusion, Truth, synthetic_bundle

    rng = np.random.default_rng(31)
    cx, cy = rng.uniform(17, 23), rng.uniform(13, 17)
    truth = Truth(inclusions=(Inclusion(jf.Ellipse(cx, cy, 4.0, 3.0, rng.uniform(0, 3)), float(rng.uniform(3, 6))),))
    noise = 0.01
    bundle = synthetic_bundle(truth, seed=31, roi=(5.0, 5.0, 35.0, 25.0), sheet=(0.0, 0.0, 40.0, 30.0), spacing=2.5,
                              noise=noise, fractions=(1.0,), h=1.5)
    obs = bundle.observations
    guide, hold = obs.mask("guide"), obs.mask("validate")
    model = MeasuredModel(bundle.experiment, obs)
    f = fit(regions_hypothesis(model, [RegionShape((cx, cy), (4.0, 3.0), 0.0, "ellipse", 3.0)], [1]), guide, hold,
            noise)
    C = drive_covariance(f, guide, noise)
    k = len(f.z)
    assert C.shape == (k, k) and np.allclose(C, C.T) and np.linalg.eigvalsh(C).min() > -1e-12 * np.abs(C).max()
    assert np.allclose(drive_covariance(f, guide, noise, sigma_drive=2 * noise), 4 * C)
    assert np.all(drive_covariance(f, guide, noise, sigma_drive=0.0) == 0)
    # one Gauss-Newton step from the converged fit on a perturbed drive moves z by M dB (to first order)
    M = drive_sensitivity(f, guide, noise)
    m = f.compiled.model
    res = Residuals.at(obs.displacements, guide, noise)
    J = res.jacobian(np.asarray(f.compiled.jacobian(f.z)))
    B = m.measured_boundary()
    for _ in range(2):
        dB = 1e-5 * rng.standard_normal(B.shape)
        r = res(np.asarray(m.predict(f.theta, boundary=B + dB))) - res(np.asarray(m.predict(f.theta, boundary=B - dB)))
        step = np.linalg.solve(J.T @ J, J.T @ r) / 2
        assert np.allclose(step, M @ dB.reshape(-1), rtol=1e-4, atol=1e-6 * np.abs(step).max()), (step, M @ dB.ravel())
    assert np.allclose(C, noise**2 * M @ M.T)
