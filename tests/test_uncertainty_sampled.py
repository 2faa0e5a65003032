"""The standard errors of a shape's quantities carried through the map from the fitted unknowns to
shapes without linearising it (refine.diagnosis.uncertainty.sampled_variance): near a circle an
ellipse's semi-axes are the eigenvalues of a noisy matrix, which the delta method gets wrong."""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import pytest

from refine.diagnosis.shapes import RegionShape
from refine.diagnosis.uncertainty import QUANTITIES, as_row, sampled_variance, shape_errors
from refine.model.parametrize import ShapeGeometry


@lru_cache
def _geometry(params0: tuple) -> ShapeGeometry:
    """One ellipse's map from shape changes (scale 1: length units) to its parameters."""
    return ShapeGeometry(None, np.array([params0], float), scale=1.0, rotate=True)


@dataclass(frozen=True)
class _Region:
    """A one-ellipse region hypothesis without a model: z = (log ratio, shape changes)."""

    params0: tuple

    def shapes_at(self, compiled, z):
        g = _geometry(self.params0).shape_params(np.asarray(z[1:], float))[0]
        return (RegionShape((g[0], g[1]), (g[2], g[3]), g[4], "ellipse", float(np.exp(z[0]))),)


@dataclass(frozen=True)
class _Fitted:
    hypothesis: _Region
    z: np.ndarray
    z_cov: np.ndarray
    compiled: object = "no model: the map to shapes needs none"

    @property
    def shapes(self):
        return self.hypothesis.shapes_at(self.compiled, self.z)


def _fitted(axes, angle, cov):
    return _Fitted(_Region((40.0, 30.0, *axes, angle)), np.r_[np.log(3.0), np.zeros(5)], cov)


def test_a_circle_s_axes_take_the_split_of_the_noisy_matrix_in_every_direction():
    # M = r I + E, entries (E11, E22, E12) of std s: each eigenvalue moves by (E11 + E22) / 2 plus
    # the split sqrt(((E11 - E22) / 2)^2 + E12^2): mean square 2 s^2; the delta method sees s^2
    s = 0.3
    cov = np.diag([0.01, 0.04, 0.04, s**2, s**2, s**2])
    f = _fitted((8.0, 8.0), 0.0, cov)
    var = sampled_variance(f, cov, draws=2000)[0]
    assert var[2] == pytest.approx(2 * s**2, rel=0.12) and var[3] == pytest.approx(2 * s**2, rel=0.12)
    assert var[0] == pytest.approx(0.04, rel=0.1)  # the centre's map is linear
    [e] = shape_errors(f)
    assert e.axes[0] == pytest.approx(np.sqrt(2) * s, rel=0.08)


def test_an_elongated_ellipse_s_errors_are_the_delta_method_s():
    # far from a circle the map is nearly linear: the draws give the first-order errors
    cov = np.diag([0.04, 0.01, 0.01, 0.02, 0.02, 0.01])
    f = _fitted((12.0, 6.0), 0.4, cov)
    from refine.diagnosis.uncertainty import quantity_jacobian

    G = quantity_jacobian(f)
    first = np.sqrt(np.einsum("qk,kl,ql->q", G, cov, G))
    sampled = as_row(shape_errors(f)[0])
    np.testing.assert_allclose(sampled, first, rtol=0.08)
    assert len(sampled) == len(QUANTITIES)


def test_errors_from_the_draws_cover_a_noisy_circle_where_the_linear_ones_fall_short():
    # a circle fitted from noisy data: its axes within 2 reported errors about 95 % of the time
    rng = np.random.default_rng(7)
    s, r = 0.3, 8.0
    cov = np.diag([1e-4, 1e-4, 1e-4, s**2, s**2, s**2])
    hits, hits_linear = [], []
    from refine.diagnosis.uncertainty import quantity_jacobian

    for _ in range(30):
        z = np.r_[np.log(3.0), 0.0, 0.0, rng.normal(0, s, 3)]
        f = _Fitted(_Region((40.0, 30.0, r, r, 0.0)), z, cov)
        a = _quantities(f)[2:4]
        std = np.sqrt(sampled_variance(f, cov, draws=150)[0, 2:4])
        G = quantity_jacobian(f)
        linear = np.sqrt(np.einsum("qk,kl,ql->q", G, cov, G))[2:4]
        hits += list(np.abs(a - r) <= 2 * std)
        hits_linear += list(np.abs(a - r) <= 2 * linear)
    assert np.mean(hits) >= 0.93
    assert np.mean(hits_linear) < np.mean(hits)


def _quantities(f):
    from refine.diagnosis.uncertainty import shape_quantities

    return shape_quantities(f.shapes)[0]
