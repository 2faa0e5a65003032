"""An ellipse's orientation error near a circle (refine.diagnosis.uncertainty.orientation_variance):
noise makes a fitted ellipse more elongated than the truth, so draws about the fit turn it too
little; taken at the unbiased elongation the errors cover the truth about 95 % of the time."""

from __future__ import annotations

import numpy as np
import pytest

from refine.diagnosis.uncertainty import orientation_variance


def _as_quantities(v: np.ndarray, size: float = 8.0) -> np.ndarray:
    """Quantity rows (:data:`QUANTITIES`) of ellipses of mean semi-axis ``size`` and deviator
    ``v (..., 2)``: semi-axes ``size +- |v|``, orientation half the deviator's direction."""
    r = np.linalg.norm(v, axis=-1)
    q = np.zeros(v.shape[:-1] + (7,))
    q[..., 2], q[..., 3] = size + r, size - r
    q[..., 4] = np.arctan2(v[..., 1], v[..., 0]) / 2
    return q


def _coverage(length: float, rng, fits: int = 300, draws: int = 200) -> tuple[float, float]:
    """Share of fits whose orientation lies within 2 errors of the truth's: the errors of
    :func:`orientation_variance` and of draws about the fit, for a true deviator of ``length``
    noise stds drawn at a random direction (Gaussian noise of std 1 per deviator entry)."""
    t = rng.uniform(0, np.pi, fits)
    v = length * np.stack([np.cos(2 * t), np.sin(2 * t)], -1)
    v_fit = v + rng.standard_normal(v.shape)
    q0 = _as_quantities(v_fit)
    q = _as_quantities(v_fit[None] + rng.standard_normal((draws, fits, 2)))
    miss = np.angle(np.exp(2j * (q0[:, 4] - t))) / 2
    ours = np.sqrt(orientation_variance(q0, q))
    about_fit = np.sqrt(np.mean((np.angle(np.exp(2j * (q[..., 4] - q0[:, 4]))) / 2) ** 2, axis=0))
    return float(np.mean(np.abs(miss) <= 2 * ours)), float(np.mean(np.abs(miss) <= 2 * about_fit))


@pytest.mark.parametrize("length", [0.7, 1.0, 1.5])
def test_near_a_circle_the_orientation_errors_cover_the_truth_where_draws_about_the_fit_fall_short(length):
    rng = np.random.default_rng(int(10 * length))
    ours, about_fit = _coverage(length, rng)
    assert 0.91 <= ours <= 0.995
    assert about_fit < ours - 0.02


def test_far_from_a_circle_the_orientation_error_is_the_draws_own_spread():
    rng = np.random.default_rng(3)
    q0 = _as_quantities(np.array([[6.0, 0.0]]))
    q = _as_quantities(np.array([[6.0, 0.0]]) + 0.3 * rng.standard_normal((2000, 1, 2)))
    spread = np.mean((q[..., 4] - q0[:, 4]) ** 2, axis=0)
    np.testing.assert_allclose(orientation_variance(q0, q), spread, rtol=0.01)
    # the deviator's direction moves by 0.3 / 6 rad per unit of noise, the orientation by half of it
    assert np.sqrt(spread[0]) == pytest.approx(0.3 / 6 / 2, rel=0.05)


def test_an_orientation_the_data_do_not_fix_gets_the_error_of_a_uniform_direction():
    rng = np.random.default_rng(4)
    q0 = _as_quantities(np.array([[0.2, 0.1]]))  # elongation well inside the noise
    q = _as_quantities(np.array([[0.2, 0.1]]) + rng.standard_normal((4000, 1, 2)))
    assert np.sqrt(orientation_variance(q0, q)[0]) == pytest.approx(np.pi / np.sqrt(12), rel=0.05)


def test_the_summary_gives_an_orientation_with_its_error_or_says_it_is_undetermined():
    from refine.diagnosis.report import UNDETERMINED_ORIENTATION, orientation

    rng = np.random.default_rng(5)
    angle, err = float(rng.uniform(0, np.pi)), float(rng.uniform(0.01, 0.3))
    finding = {"region": {"angle": angle - np.pi}, "std": {"angle": 0.9}, "total_std": {"angle": err}}
    assert orientation(finding) == f", axis a at {np.degrees(angle):.0f} +- {np.degrees(err):.0f} deg"
    finding["total_std"]["angle"] = UNDETERMINED_ORIENTATION / 2
    assert "orientation undetermined" in orientation(finding)
    assert orientation({"region": {"angle": angle}}) == f", axis a at {np.degrees(angle):.0f} deg"  # no errors
    assert orientation({"region": {"axes": [1.0, 1.0]}}) == ""  # an older finding without an angle


def test_the_orientation_error_does_not_depend_on_which_axis_is_called_a():
    # the same ellipse with its axes named the other way round (b > a, turned a quarter)
    rng = np.random.default_rng(6)
    q0 = _as_quantities(np.array([[1.5, 0.5]]))
    q = _as_quantities(np.array([[1.5, 0.5]]) + 0.4 * rng.standard_normal((1000, 1, 2)))
    swapped = lambda x: x[..., [0, 1, 3, 2, 4, 5, 6]] + np.eye(7)[4] * np.pi / 2  # noqa: E731
    np.testing.assert_allclose(orientation_variance(swapped(q0), swapped(q)), orientation_variance(q0, q), rtol=1e-9)
    assert np.sqrt(orientation_variance(q0, q)[0]) < 0.3
