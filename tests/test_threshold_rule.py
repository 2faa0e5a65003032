"""When a strain curve has a threshold at all (refine.threshold.ThresholdRule, Threshold.rise): a
hinge fits every curve, so a curve that bends evenly must be told apart from one whose growth
rate jumps; the same rule for a truth and its estimate."""

import numpy as np
import pytest

from refine.exceptions import ObservationError
from refine.threshold import ThresholdRule, strain_threshold


def _hinge(rng, rise, n=20):
    """A curve growing at rate b, then ``rise`` times faster past a threshold drawn at 55-90 % of a
    motion of random length, with noise 1 % of the final strain; its threshold's fraction."""
    x = np.linspace(0.0, rng.uniform(20.0, 120.0), n)
    f = rng.uniform(0.55, 0.9)
    b = rng.uniform(0.001, 0.005)
    s = b * x + b * (rise - 1) * np.maximum(x - f * x[-1], 0.0)
    return x, s + rng.normal(0.0, 0.01 * s.max(), n), f


def _even_bend(rng, rise, n=20):
    """A curve whose growth rate rises evenly (a parabola) by ``rise`` over its motion, with the
    same noise as :func:`_hinge`."""
    x = np.linspace(0.0, rng.uniform(20.0, 120.0), n)
    b = rng.uniform(0.001, 0.005)
    s = b * x + b * (rise - 1) * x**2 / (2 * x[-1])
    return x, s + rng.normal(0.0, 0.01 * s.max(), n)


def test_a_jump_of_the_growth_rate_is_a_threshold_and_an_even_bend_of_8_percent_is_not():
    rng = np.random.default_rng(25)
    rule = ThresholdRule()
    jumps, bends, near = [], [], []
    for _ in range(40):
        x, s, f = _hinge(rng, rng.uniform(1.6, 4.0))
        found = rule.find(x, s)
        jumps.append(found.found)
        near.append(abs(found.hinge.fraction - f) <= 0.05)
        bends.append(rule.find(*_even_bend(rng, 1.08)).found)
    assert np.mean(jumps) >= 0.95 and np.mean(near) >= 0.9, (np.mean(jumps), np.mean(near))
    assert np.mean(bends) <= 0.1, np.mean(bends)


def test_a_parabolas_hinge_sits_near_its_middle_whatever_its_curvature():
    """Why a rule is needed: without noise, an even bend's hinge is at about half the motion for a
    slight and a strong bend alike; only its rise tells them apart."""
    x = np.linspace(0.0, 50.0, 25)
    for rise in (1.05, 1.5, 3.0):
        th = strain_threshold(x, 0.004 * x + 0.004 * (rise - 1) * x**2 / 100.0, rising=True)
        assert th.fraction == pytest.approx(0.5, abs=0.05)
        assert 1 < th.rise < rise  # two segments share the bend: each carries part of it


def test_rise_is_the_ratio_of_the_slopes_for_either_direction_of_motion():
    rng = np.random.default_rng(7)
    x, s, _ = _hinge(rng, 2.5, n=40)
    up, down = strain_threshold(x, s, rising=True), strain_threshold(-x, s, rising=True)
    assert up.rise == pytest.approx(up.slopes[1] / up.slopes[0])
    assert down.rise == pytest.approx(up.rise, rel=1e-6)
    assert up.to_json()["rise"] == up.rise
    flat_then_up = strain_threshold(x, np.maximum(x - x[25], 0.0) + rng.normal(0, 1e-3, x.size))
    assert flat_then_up.rise > 10 or flat_then_up.rise == np.inf


@pytest.mark.parametrize("kwargs, words", [({"min_rise": 1.0}, "min_rise must exceed 1"),
                                           ({"min_rise": 0.5}, "min_rise must exceed 1"),
                                           ({"alpha": 0.0}, "alpha must be between 0 and 1"),
                                           ({"alpha": 1.5}, "alpha must be between 0 and 1")])
def test_a_rule_that_cannot_be_met_is_a_clear_error(kwargs, words):
    with pytest.raises(ObservationError, match=words):
        ThresholdRule(**kwargs)


def test_a_finding_reports_the_threshold_with_its_interval_or_none_with_why_and_keeps_the_hinge():
    """ThresholdRule.find, the one definition: the rising hinge judged by the rule; its JSON puts a
    threshold's place and interval at the top (what examples.hand.plot_curves draws) and says why
    where there is none, the hinge's figures beside either answer."""
    rng = np.random.default_rng(11)
    rule = ThresholdRule()
    x, s, f = _hinge(rng, rng.uniform(2.0, 3.0), n=30)
    yes = rule.find(x, s)
    assert yes.found and yes.threshold is yes.hinge and yes.why_none is None
    assert yes.hinge == strain_threshold(x, s, rising=True) and yes.hinge.fraction == pytest.approx(f, abs=0.05)
    j = yes.to_json()
    assert j["has_threshold"] and j["fraction"] == yes.hinge.fraction and j["motion"] == yes.hinge.motion
    assert j["interval"][0] < j["motion"] < j["interval"][1] and j["std"] > 0
    assert j["hinge"]["rise"] == yes.hinge.rise and j["rule"] == {"min_rise": 1.25, "alpha": 0.01}
    xb = np.linspace(0.0, 60.0, 30)
    bend = rule.find(xb, 0.004 * xb * (1 + 0.08 * xb / 120.0) + rng.normal(0.0, 1e-5, xb.size))  # rate +8 %, evenly
    no = bend.to_json()
    assert not bend.found and bend.threshold is None and not no["has_threshold"] and bend.hinge.p_value < 0.01
    assert "motion" not in no and "fraction" not in no and no["why_none"].startswith("the growth rate rises only")
    assert no["hinge"]["fraction"] == bend.hinge.fraction  # the hinge's place is kept, not called a threshold
    line = rule.find(x, 0.003 * x + rng.normal(0.0, 0.01, x.size))
    assert not line.found and "F test" in line.why_none
    slows = rule.find(x, np.minimum(x, x[15]) * 0.003)  # growth that stops: no faster growth anywhere
    assert not slows.found and slows.hinge.rise == 1.0 and "does not rise" in slows.why_none
    with pytest.raises(ObservationError, match="at least 6 samples"):
        rule.find(x[:4], s[:4])
