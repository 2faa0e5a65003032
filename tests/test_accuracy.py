"""Accuracy where the data allow it (issue 22, item 4): a noise-free rectangle from an independent
finer solve recovered within 1 %, and a standard error for every fitted quantity.

Cases are drawn at random under a seed (place, size, ratio); data come from a larger sheet meshed
with quadratic triangles that follow the hidden shape (refine.demo_data), never from the
inversion's own mesh. ``benchmarks/error_coverage.py`` measures the coverage of the errors over many
cases and the noise-free accuracy over more rectangles.
"""

from types import SimpleNamespace

import numpy as np
import pytest

import jaxfem as jf
from refine.diagnosis.findings import findings
from refine.diagnosis.shapes import Hole, RegionShape
from refine.diagnosis.uncertainty import QUANTITIES, quantity_jacobian, shape_errors, shape_quantities


class _Linear:
    """A hypothesis whose shape is a known smooth map of z: ``(log ratio, cx, cy, a, b, angle)``."""

    def __init__(self, kind):
        self.kind = kind

    def shapes_at(self, compiled, z):
        if self.kind == "hole":
            return (Hole((z[1], z[2]), (z[3], z[4]), z[5]),)
        return (RegionShape((z[1], z[2]), (z[3], z[4]), z[5], self.kind, float(np.exp(z[0]))),)


@pytest.mark.parametrize("kind", ["ellipse", "rectangle", "hole"])
def test_errors_are_the_covariance_carried_to_every_quantity(kind):
    """The delta method on a map whose derivatives are known: ratio e^z0 (std ratio x std z0),
    area pi a b or 4 a b (std from both axes and their correlation), the rest as given; the
    reported errors (from draws through the map: shape_errors) agree with it within the draws'
    own scatter (1000 draws: about 2 % of a standard error), the map being nearly linear here."""
    rng = np.random.default_rng(3)
    z = np.array([np.log(rng.uniform(2, 8)), *rng.uniform(30, 60, 2), *rng.uniform(5, 12, 2), rng.uniform(0, 1)])
    L = rng.normal(size=(6, 6)) * 0.05
    cov = L @ L.T + np.diag(rng.uniform(0.01, 0.04, 6))
    hyp = _Linear(kind)
    f = SimpleNamespace(hypothesis=hyp, compiled=None, z=z, z_cov=cov, shapes=hyp.shapes_at(None, z))
    f.compiled = object()
    G = quantity_jacobian(f)
    linear = np.sqrt(np.einsum("qk,kl,ql->q", G, cov, G))
    sd = np.sqrt(np.diag(cov))
    assert np.allclose(linear[:5], sd[1:], rtol=1e-5)
    c = np.pi if kind != "rectangle" else 4.0
    g = c * np.array([z[4], z[3]])  # d area / d (a, b)
    assert linear[5] == pytest.approx(np.sqrt(g @ cov[3:5, 3:5] @ g), rel=1e-5)
    [e] = shape_errors(f)
    assert np.allclose([*e.centroid, *e.axes, e.area], linear[[0, 1, 2, 3, 5]], rtol=0.08)
    if kind == "rectangle":
        assert e.angle == pytest.approx(linear[4], rel=0.08)
    else:
        # an ellipse's or hole's orientation error is taken at the unbiased elongation
        # (uncertainty.orientation_variance, checked in tests/test_uncertainty_orientation.py):
        # never below the delta method's, and here (an angle std of 0.26 rad) somewhat above it
        assert 0.95 * linear[4] <= e.angle <= 1.25 * linear[4]
    if kind == "hole":
        assert e.relative_elasticity is None
    else:
        assert linear[6] == pytest.approx(np.exp(z[0]) * sd[0], rel=1e-5)
        # the ratio's error comes from draws of the region's strength (refine.diagnosis.valley,
        # checked in tests/test_uncertainty_valley.py): it follows the size-ratio valley's bend,
        # which the delta method's tangent misses, so it is never much below the delta method's
        # and here somewhat above it (0.85 against 0.69 on the ellipse)
        assert 0.95 * linear[6] <= e.relative_elasticity <= 1.5 * linear[6], (e.relative_elasticity, linear[6])
    assert len(shape_quantities(f.shapes)[0]) == len(QUANTITIES)


SMALL = {"roi": (20.0, 10.0, 80.0, 50.0), "sheet": (0.0, 0.0, 100.0, 60.0), "sides": ((14, 20), (10, 14))}
"""A 60 x 40 mm region of interest (117 points on a 5 mm grid) in a 100 x 60 mm sheet."""
FULL = {"roi": (20.0, 10.0, 120.0, 70.0), "sheet": (0.0, 0.0, 140.0, 80.0), "sides": ((20, 30), (14, 22))}
"""The 100 x 60 mm region of interest of the other tests (273 points) in a 140 x 80 mm sheet."""


def _rectangle_case(seed: int, size: dict):
    """A rectangle of random place, sides (in ``size["sides"]``, mm) and ratio (3-10) at least
    a third of its sides away from the region of interest's edges."""
    from refine.demo_data import Inclusion, Truth

    rng = np.random.default_rng(seed)
    (w0, w1), (h0, h1) = size["sides"]
    w, h = rng.uniform(w0, w1), rng.uniform(h0, h1)
    x0, y0, x1, y1 = size["roi"]
    cx, cy = rng.uniform(x0 + 0.85 * w, x1 - 0.85 * w), rng.uniform(y0 + 0.85 * h, y1 - 0.85 * h)
    ratio = float(rng.uniform(3, 10))
    return Truth(inclusions=(Inclusion(jf.Rect(cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2), ratio),))


# Both slow (80 s and minutes on 2 cores; the suite is near its 15 minutes): benchmarks/error_coverage.py
# measures noise-free rectangles within 1 % (3 cases, at most 0.34 %).
@pytest.mark.slow
@pytest.mark.parametrize("size", [SMALL, FULL], ids=["small", "full"])
def test_a_noise_free_rectangle_is_recovered_within_one_percent(size):
    """Noise-free data of a random rectangle (independent finer quadratic solve, 5 mm grid, two
    frames); the rectangle hypothesis fitted from a start off the truth (centre 1.5 mm, sides
    10-15 %, 0.05 rad, ratio 3), then refitted on every guide point with quadratic triangles
    at its fit (as the diagnosis does its chosen model): ratio within 1 %, centre within 0.3 mm,
    area within 2 %; its finding reports a standard error for every quantity. (The full size
    takes minutes: slow; the small one 75 s at load 2-5 on 2 cores; ``benchmarks/error_coverage.py
    --noise 0 --kinds rectangle`` measures more.)"""
    from refine.diagnosis.fitted import refit
    from refine.diagnosis.regions import fit_regions
    from refine.model.measured import MeasuredModel
    from refine.demo_data import synthetic_bundle

    truth = _rectangle_case(4101, size)
    rect, ratio = truth.inclusions[0].shape, truth.inclusions[0].ratio
    bundle = synthetic_bundle(truth, seed=4101, roi=size["roi"], sheet=size["sheet"], spacing=5.0, noise=0.0,
                              fractions=(0.5, 1.0))
    model = MeasuredModel(bundle.experiment, bundle.observations)
    guide, hold = bundle.observations.mask("guide"), bundle.observations.mask("validate")
    cx, cy, a, b, _ = rect.params
    start = RegionShape((cx + 1.5, cy - 1.0), (0.87 * a, 1.13 * b), 0.05, "rectangle", 3.0)
    f = refit(fit_regions(model, [start], [1], guide, hold, 1e-3), guide, hold, 1e-3, element="tri6")
    [s] = f.shapes
    assert s.kind == "rectangle"
    assert abs(s.ratio / ratio - 1) < 0.01, (s, ratio)
    assert np.hypot(s.centre[0] - cx, s.centre[1] - cy) < 0.3, (s, rect)
    assert abs(4 * s.axes[0] * s.axes[1] / rect.area - 1) < 0.02, (s, rect)
    [finding] = findings(f, "e", None)
    std = finding["std"]
    values = [*std["centroid"], *std["axes"], std["angle"], std["area"], std["relative_elasticity"]]
    assert all(v is not None and np.isfinite(v) and v > 0 for v in values), std
    assert finding["relative_elasticity_std"] == pytest.approx(std["relative_elasticity"], rel=1e-3, abs=1e-4)


@pytest.mark.slow  # a whole diagnosis with its rectangle fits: 165 s at load 4 on 2 cores
def test_the_papers_rectangle_without_noise_is_named_a_rectangle():
    """The paper's Sec. 3.1 rectangle (ratio 10, 10 mm grid) on noise-free data from an
    independent finer solve: the default diagnosis tries a rectangle (its ellipse leaves misfit
    above the null level) and names it; ratio within 2 % (fitted as an ellipse it came out 5.4 %
    low; on a 10 mm grid the boundary points' linear interpolation alone moves it 1.7 % with the
    rectangle known), centre within 0.5 mm, area within 3 %."""
    from refine.diagnosis import diagnose
    from examples.paper.experiment import BACKGROUND, INCLUSION, EmbeddedRectangle

    cfg = EmbeddedRectangle(noise=0.0)
    d = diagnose(cfg.bundle(), log=lambda m: None)
    [f] = d.findings
    assert f["region"]["shape"] == "rectangle", d.chosen.describe()
    assert abs(f["relative_elasticity"] / (INCLUSION / BACKGROUND) - 1) < 0.02, f
    cx, cy = cfg.shape.params[:2]
    assert np.hypot(f["region"]["centroid"][0] - cx, f["region"]["centroid"][1] - cy) < 0.5
    assert abs(f["region"]["area"] / cfg.shape.area - 1) < 0.03
    assert f["std"]["relative_elasticity"] > 0
