"""Error measures (eqs. 1 and 9), least-squares residuals, and the elasticity formulas (eqs. 6-8)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from refine.diagnosis.elasticity import STANDARD_GRAVITY, apparent_modulus, relative_elasticity, strip_modulus
from refine.measures import (displacement_error, mean_position_error, misfit, residual_mask, tracking_error, weighted_residuals)
from refine.exceptions import ExperimentError, ObservationError

jax.config.update("jax_enable_x64", True)


def two_frames():
    """Measured (2 frames, 3 points, 2D) with point 2 lost in frame 2, and a prediction."""
    measured = np.array([[[1.0, 0.0], [0.0, 2.0], [3.0, 4.0]],
                         [[2.0, 0.0], [0.0, 4.0], [np.nan, np.nan]]])
    predicted = measured.copy()
    predicted[0, 0] += [0.0, 0.5]    # miss 0.5, motion 1
    predicted[0, 2] += [0.3, 0.4]    # miss 0.5, motion 5
    predicted[1, 1] += [0.6, 0.8]    # miss 1.0, motion 4
    predicted[1, 2] = [9.0, 9.0]     # lost in the measurement: ignored
    return predicted, measured


def test_displacement_error_is_eq1_sum_of_distances():
    predicted, measured = two_frames()
    e = displacement_error(predicted, measured)
    assert e.value == pytest.approx(0.5 + 0.5 + 1.0) and (e.n_used, e.n_skipped) == (5, 1)
    # positions or displacements: the same reference cancels
    reference = np.array([[5.0, 5.0], [1.0, 2.0], [0.0, 7.0]])
    assert displacement_error(predicted + reference, measured + reference).value == pytest.approx(e.value)


def test_mean_position_error():
    predicted, measured = two_frames()
    e = mean_position_error(predicted, measured)
    assert e.value == pytest.approx(2.0 / 5) and e.n_used == 5
    assert np.isnan(mean_position_error(measured[1:, 2:], measured[1:, 2:]).value)


def test_tracking_error_is_eq9_mean_of_ratios():
    predicted, measured = two_frames()
    e = tracking_error(predicted, measured)
    # eq. 9: (1/n) sum |q - q~| / |q - r|, not sum |q - q~| / sum |q - r|
    assert e.value == pytest.approx((0.5 / 1 + 0 / 2 + 0.5 / 5 + 0 / 2 + 1.0 / 4) / 5)
    assert e.value != pytest.approx(2.0 / (1 + 2 + 5 + 2 + 4))
    assert (e.n_used, e.n_skipped) == (5, 1)


def test_tracking_error_skips_points_that_did_not_move():
    measured = np.array([[[0.0, 0.0], [1.0, 0.0]]])
    predicted = np.array([[[0.1, 0.0], [1.1, 0.0]]])
    e = tracking_error(predicted, measured)
    assert e.value == pytest.approx(0.1) and (e.n_used, e.n_skipped) == (1, 1)
    assert tracking_error(predicted, measured, min_motion=2.0).n_used == 0


def test_bad_predictions_are_refused():
    predicted, measured = two_frames()
    predicted[0, 1] = np.nan
    with pytest.raises(ObservationError, match="predicted displacements contain NaN"):
        displacement_error(predicted, measured)
    with pytest.raises(ObservationError, match="shape"):
        tracking_error(predicted[:1], measured)


def test_weighted_residuals_and_mask():
    predicted, measured = two_frames()
    r, mask = weighted_residuals(predicted, measured, noise_std=0.5)
    assert mask.tolist() == [True] * 10 + [False] * 2 and np.array_equal(mask, residual_mask(measured))
    np.testing.assert_allclose(r, ((predicted - measured).reshape(-1)[mask]) / 0.5)
    assert misfit(r) == pytest.approx(0.5 * np.sum(r**2))
    assert misfit(r) == pytest.approx(0.5 * (0.5**2 + 0.5**2 + 1.0**2) / 0.25)
    unweighted, _ = weighted_residuals(predicted, measured)
    np.testing.assert_allclose(unweighted, r * 0.5)
    # a sigma per point broadcasts over the components
    per_point, _ = weighted_residuals(predicted, measured, noise_std=np.array([[1.0], [2.0], [4.0]]))
    assert per_point[6] == pytest.approx((predicted[1, 0, 0] - measured[1, 0, 0]) / 1.0)
    assert per_point[9] == pytest.approx((predicted[1, 1, 1] - measured[1, 1, 1]) / 2.0)
    with pytest.raises(ObservationError, match="noise_std must be positive"):
        weighted_residuals(predicted, measured, noise_std=0.0)


def test_weighted_residuals_are_differentiable_in_jax():
    predicted, measured = two_frames()
    sigma = 0.1
    jacobian = jax.jacfwd(lambda p: weighted_residuals(p, measured, sigma)[0])(jnp.asarray(predicted))
    _, mask = weighted_residuals(predicted, measured, sigma)
    # d r / d u~ is the identity over the flattened prediction, masked like the residuals
    np.testing.assert_allclose(np.asarray(jacobian).reshape(mask.sum(), -1), np.eye(mask.size)[mask] / sigma)
    value = jax.jit(lambda p: misfit(weighted_residuals(p, measured, sigma)[0]))(jnp.asarray(predicted))
    assert float(value) == pytest.approx(misfit(weighted_residuals(predicted, measured, sigma)[0]))


def test_strip_modulus_eq6():
    # 100 g on a strip 100 mm long, 10 mm x 1 mm, stretched 10 mm: E = m g L / (A dL)
    e = strip_modulus(length=0.1, area=10e-3 * 1e-3, elongation=0.01, mass=0.1)
    assert e == pytest.approx(0.1 * STANDARD_GRAVITY * 0.1 / (1e-5 * 0.01))
    assert strip_modulus(0.1, 1e-5, 0.01, force=0.1 * STANDARD_GRAVITY) == pytest.approx(e)
    np.testing.assert_allclose(strip_modulus(0.1, 1e-5, np.array([0.01, 0.02]), mass=0.1), [e, e / 2])
    with pytest.raises(ExperimentError, match="exactly one of"):
        strip_modulus(0.1, 1e-5, 0.01, force=1.0, mass=0.1)
    with pytest.raises(ExperimentError, match="positive"):
        strip_modulus(0.1, 0.0, 0.01, force=1.0)


def test_relative_elasticity_eqs7_8():
    # Only E b is observable: fitting both regions with an assumed thickness gives E_R directly.
    e1, b1, e2, b2, assumed = 83.76, 1.2, 837.61, 0.7, 1.0
    fitted1, fitted2 = apparent_modulus(e1, b1, assumed), apparent_modulus(e2, b2, assumed)
    assert relative_elasticity(fitted2, fitted1) == pytest.approx(e2 * b2 / (e1 * b1))
    assert relative_elasticity(e2, e1, b2, b1) == pytest.approx(e2 * b2 / (e1 * b1))
    assert relative_elasticity(0.0, e1) == 0.0  # a hole
    with pytest.raises(ExperimentError):
        relative_elasticity(1.0, 0.0)
