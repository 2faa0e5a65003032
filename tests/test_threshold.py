"""The strain threshold detector (refine.threshold): where a maximum-strain vs motion curve
changes its growth rate, with a profile-likelihood interval, on generated curves with a random
threshold and noise; and its errors for curves it cannot read."""

import numpy as np
import pytest

from refine.exceptions import ObservationError
from refine.threshold import strain_threshold


def _curve(rng, n=None, fraction=None, decreasing=False):
    """A hinge curve: strain growing at rate b, then r times faster after the threshold (drawn
    at 60-95 % of a motion of random length), sampled at n frames, noise 1 % of the final strain."""
    n = int(rng.integers(20, 61)) if n is None else n
    x = np.linspace(0.0, rng.uniform(10.0, 40.0), n)
    f = rng.uniform(0.6, 0.95) if fraction is None else fraction
    x0 = f * x[-1]
    b, r = rng.uniform(0.002, 0.01), rng.uniform(2.0, 5.0)
    s = b * x + b * (r - 1) * np.maximum(x - x0, 0.0)
    s = s + rng.normal(0.0, 0.01 * s.max(), n)
    return (-x if decreasing else x), s, f, (-x0 if decreasing else x0)


def test_threshold_found_within_5_percent_and_inside_its_interval_over_200_curves():
    rng = np.random.default_rng(2025)
    near, inside = [], []
    for _ in range(200):
        x, s, f, x0 = _curve(rng)
        th = strain_threshold(x, s)
        near.append(abs(th.fraction - f) <= 0.05)
        inside.append(th.interval[0] <= x0 <= th.interval[1])
        assert th.interval[0] <= th.motion <= th.interval[1]
        assert th.p_value < 1e-3  # the rate does change
    assert np.mean(near) >= 0.95, np.mean(near)
    assert 0.90 <= np.mean(inside) <= 0.99, np.mean(inside)  # a 95 % interval, 200 curves


def test_a_decreasing_motion_gives_the_same_threshold_and_slopes_of_its_sign():
    rng = np.random.default_rng(3)
    x, s, f, x0 = _curve(rng, n=40, fraction=0.85)
    up, down = strain_threshold(x, s), strain_threshold(-x, s)
    assert down.motion == pytest.approx(-up.motion, rel=1e-6)
    assert down.fraction == pytest.approx(up.fraction, rel=1e-6)
    assert down.slopes == pytest.approx((-up.slopes[0], -up.slopes[1]), rel=1e-6)
    assert abs(up.fraction - 0.85) < 0.05 and up.slopes[1] > up.slopes[0] > 0


def test_a_straight_curve_shows_no_significant_change():
    rng = np.random.default_rng(4)
    x = np.linspace(0, 20, 40)
    p = [strain_threshold(x, 0.01 * x + rng.normal(0, 0.002, x.size)).p_value for _ in range(20)]
    assert np.median(p) > 0.1


@pytest.mark.parametrize("motion, strain, words", [
    (np.arange(5.0), np.arange(5.0), "at least 6 samples"),
    (np.arange(8.0), np.r_[np.arange(7.0), np.nan], "strain is not finite at sample(s) [7]"),
    (np.r_[0, 1, 2, np.inf, 4, 5, 6.0], np.arange(7.0), "motion is not finite"),
    (np.array([0, 1, 2, 1.5, 3, 4, 5.0]), np.arange(7.0), "strictly monotone"),
    (np.array([0, 1, 1, 2, 3, 4, 5.0]), np.arange(7.0), "strictly monotone"),
    (np.arange(7.0), np.arange(6.0), "one length"),
])
def test_curves_it_cannot_read_are_clear_errors(motion, strain, words):
    with pytest.raises(ObservationError, match=words.replace("(", r"\(").replace(")", r"\)")
                       .replace("[", r"\[").replace("]", r"\]")):
        strain_threshold(motion, strain)


def test_rising_counts_only_a_change_to_faster_growth():
    """``rising=True``: on curves that speed up (drawn as in the 200-curve test) it is the free
    hinge; on their mirror images, which slow down by as much, it finds no significant change."""
    rng = np.random.default_rng(11)
    for _ in range(20):
        x, s, f, x0 = _curve(rng)
        free, up = strain_threshold(x, s), strain_threshold(x, s, rising=True)
        assert up.fraction == pytest.approx(free.fraction, abs=1e-9) and up.p_value == pytest.approx(free.p_value)
        slowing = -s + (s[-1] + s[0]) * x / x[-1]  # the same change, to slower growth
        assert strain_threshold(x, slowing).p_value < 1e-3
        down = strain_threshold(x, slowing, rising=True)
        assert down.p_value > 0.05 and down.slopes[1] >= down.slopes[0] - 1e-12
