"""A region's ratio error along the size-ratio valley (refine.diagnosis.valley): the data fix a
region's strength, area x (r - 1) / (r + 1), and a stiff region's ratio climbs steeply as its
area shrinks at that strength, which a Gaussian in the fit's own unknowns (log ratio, shape)
follows only along its tangent."""

from __future__ import annotations

import numpy as np
import pytest

from refine.diagnosis.uncertainty import quantity_jacobian, sampled_variance
from refine.diagnosis.valley import contrast, ratio_along_valley, ratio_of
from test_uncertainty_sampled import _Fitted, _Region


def test_the_strength_gives_back_the_ratio_up_to_a_rigid_region_and_down_to_a_hole():
    for r in (0.05, 0.5, 1.0, 3.0, 40.0):
        assert ratio_of(100.0 * contrast(r), 100.0) == pytest.approx(r)
    assert ratio_of(101.0, 100.0) == np.inf and ratio_of(-101.0, 100.0) == 0.0
    assert contrast(1.0) == 0.0 and ratio_along_valley(2.0, 1.0) == pytest.approx(2.0)
    assert ratio_along_valley(16.0, 1 / 1.15) is None  # stiffer than rigid


def _circle(radius: float, ratio: float, area_std: float):
    """A fitted circle whose data fix its strength and leave its area uncertain by ``area_std``
    (relative): the covariance of z = (log ratio, shape changes) along the valley's tangent."""
    f = _Fitted(_Region((40.0, 30.0, radius, radius, 0.0)), np.r_[np.log(ratio), np.zeros(5)], np.eye(6))
    G = quantity_jacobian(f)
    wider, *_ = np.linalg.lstsq(G[[0, 1, 2, 3], 1:], [0.0, 0.0, radius, radius], rcond=None)  # radius x (1 + e)
    c = contrast(ratio)
    v = np.r_[-2 * c * 2 / (1 - c**2), wider]  # dA / A = 2 e; d ln r = -2c dA / (A (1 - c^2)) keeps A c
    cov = (area_std / 2) ** 2 * np.outer(v, v) + 1e-10 * np.eye(6)
    return _Fitted(f.hypothesis, f.z, cov)


@pytest.mark.parametrize("off", [1.5, -1.5, 0.5])
def test_a_stiff_region_s_ratio_error_covers_the_valley_where_the_tangent_falls_short(off):
    # truth: radius 8.35, ratio 8.7 (seed 9412's); a fit of the same strength whose area came out
    # ``off`` errors (8 %) too large is less stiff (9412: 5.5): its ratio error reaches the truth,
    # the tangent's (the delta method's) does not; too small or near, both do
    r_true, ratio_true, area_std = 8.35, 8.7, 0.08
    e = off * area_std
    ratio = float(ratio_of(contrast(ratio_true), 1 + e))
    f = _circle(r_true * np.sqrt(1 + e), ratio, area_std)
    std = np.sqrt(sampled_variance(f, f.z_cov)[0, 6])
    G = quantity_jacobian(f)
    linear = np.sqrt(G[6] @ f.z_cov @ G[6])
    assert abs(ratio - ratio_true) <= 2 * std
    assert (abs(ratio - ratio_true) <= 2 * linear) == (off < 1)
    assert std > linear or off < 0


def test_a_ratio_the_data_bound_from_below_only_has_an_infinite_error():
    f = _circle(8.0, 16.0, 0.12)  # 2 errors of the area reach a region stiffer than rigid
    assert np.isinf(sampled_variance(f, f.z_cov, draws=400)[0, 6])
    g = _circle(8.0, 1.3, 0.05)  # nearly the background's: the valley is straight, as first order
    G = quantity_jacobian(g)
    assert np.sqrt(sampled_variance(g, g.z_cov, draws=2000)[0, 6]) == pytest.approx(np.sqrt(G[6] @ g.z_cov @ G[6]), rel=0.1)
