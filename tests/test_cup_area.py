"""The hole's area extrapolated on the area the model's mesh cuts (refine.solid.hole_area; the
cup holder benchmark's area error, benchmarks/README.md, diagnose3d, session 24)."""

from __future__ import annotations

from dataclasses import dataclass, replace
from types import SimpleNamespace

import numpy as np
import pytest

import jaxfem as jf
from jaxfem.mesher import domain
from jaxfem.shapes import curve_nodes
from refine.diagnosis.shapes import Hole
from refine.solid.hole_area import cut_fraction, extrapolated_area

R_IN = 8.0


@dataclass(frozen=True)
class Recipe:
    """The part of :class:`refine.solid.local.Local` the polygon needs."""

    h: float
    floor_h: float | None = None
    shape = SimpleNamespace(r_in=R_IN)

    def hole_h(self, hole):
        return None

    def coarser(self, h):
        return replace(self, h=h)


def _hole(seed):
    rng = np.random.default_rng(seed)
    a, b = rng.uniform(1.8, 3.2), rng.uniform(1.2, 2.4)
    r, phi = rng.uniform(0, R_IN - max(a, b) - 1.2), rng.uniform(0, 2 * np.pi)
    return jf.Ellipse(r * np.cos(phi), r * np.sin(phi), a, b, rng.uniform(0, np.pi))


def _shoelace(x):
    return 0.5 * abs(x[:, 0] @ np.roll(x[:, 1], -1) - x[:, 1] @ np.roll(x[:, 0], -1))


@pytest.mark.parametrize("seed", [3])
def test_the_cut_fraction_is_the_plans_missing_area(seed):
    """The polygon's share of the ellipse equals what the floor's triangles leave out of the floor's
    own polygon (a second way to the same area), below 1 and nearer 1 on a finer plan."""
    e = _hole(seed)
    coarse, fine = cut_fraction(Recipe(1.2), e), cut_fraction(Recipe(1.2), e, 0.6)
    plan = domain(jf.Ellipse(0.0, 0.0, R_IN, R_IN), 1.2, holes=(e,), curve_h=[None])
    x = plan.nodes[plan.cells]
    u, v = x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]
    triangles = 0.5 * np.abs(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]).sum()
    floor = _shoelace(plan.nodes[curve_nodes(plan, jf.Ellipse(0.0, 0.0, R_IN, R_IN))])
    assert coarse == pytest.approx((floor - triangles) / e.area, rel=1e-9)
    assert 0.9 < coarse < fine < 1.0, (coarse, fine)


@pytest.mark.parametrize("seed", [5])
def test_the_extrapolation_removes_an_order_two_error_of_the_cut_area(seed):
    """Fits whose cut areas miss the truth by k h^2 (the fine at h, the coarse at sqrt(2) h, each
    with the polygon of the ellipse its mesh was built at) extrapolate to the truth."""
    rng = np.random.default_rng(seed)
    e, h, k, truth = _hole(seed), rng.uniform(1.0, 1.4), rng.uniform(-0.03, 0.03), rng.uniform(8, 14)
    local = Recipe(h)
    f_fine = cut_fraction(local, e, h)  # meshed at e, the fit moved it to e scaled (an affine map)
    fine = truth * (1 - k * h**2) / f_fine
    scale = np.sqrt(fine / e.area)
    fitted_e = jf.Ellipse(e.cx, e.cy, e.rx * scale, e.ry * scale, e.angle)
    coarse = truth * (1 - 2 * k * h**2) / cut_fraction(local, fitted_e, np.sqrt(2) * h)  # meshed at the fine fit
    fitted = SimpleNamespace(hypothesis=SimpleNamespace(h=None, local=local, hole=e),
                             shapes=(Hole((e.cx, e.cy), (e.rx * scale, e.ry * scale), e.angle),),
                             q_disc_signed=np.array([[0, 0, 0, 0, 0, coarse - fine, 0]], float))
    out = extrapolated_area(fitted)
    assert out["fraction_fine"] == pytest.approx(f_fine, rel=1e-9)
    assert out["area"] == pytest.approx(truth, rel=1e-9)
    assert extrapolated_area(replace_signed(fitted, None)) is None


def replace_signed(fitted, signed):
    return SimpleNamespace(**{**vars(fitted), "q_disc_signed": signed})


def test_the_discretisation_error_keeps_its_sign_beside_its_size(monkeypatch):
    """with_discretisation keeps the mesh's estimate signed in ``q_disc_signed`` (side by side on a
    pool too) while ``q_disc`` and its parts stay sizes; no estimate leaves the fit as it was."""
    from concurrent.futures import ThreadPoolExecutor

    import refine.diagnosis.uncertainty as u

    @dataclass(frozen=True)
    class Fit:
        q_disc: object = None
        q_disc_parts: object = None
        q_disc_signed: object = None

    row = np.random.default_rng(7).normal(size=(1, 7))
    monkeypatch.setattr(u, "discretisation_bias", lambda f, p, h, s, signed=False: row if signed else np.abs(row))
    monkeypatch.setattr(u, "drive_bias", lambda f, p, h, s: None)
    with ThreadPoolExecutor(1) as pool:
        for g in (u.with_discretisation(Fit(), None, None, 1.0), u.with_discretisation(Fit(), None, None, 1.0, pool)):
            np.testing.assert_array_equal(g.q_disc_signed, row)
            np.testing.assert_array_equal(g.q_disc, np.abs(row))
            assert set(g.q_disc_parts) == {"mesh"}
    monkeypatch.setattr(u, "discretisation_bias", lambda f, p, h, s, signed=False: None)
    assert u.with_discretisation(Fit(), None, None, 1.0) == Fit()


@dataclass(frozen=True)
class LayeredRecipe(Recipe):
    """A recipe with the floor's elements through its thickness (None: bottom / h rounded)."""

    layers: int | None = None
    shape = SimpleNamespace(r_in=R_IN, bottom=3.0)


@dataclass(frozen=True)
class FakeHole:
    """The part of :class:`refine.solid.local.SolidHole` the grid's refits use."""

    local: LayeredRecipe
    hole: jf.Ellipse
    h: float | None = None

    def at(self, shapes, element):
        s = shapes[0]
        return replace(self, hole=jf.Ellipse(*s.centre, *s.axes, s.angle))


@pytest.mark.parametrize("seed", [11])
def test_the_grid_extrapolates_a_bilinear_error_in_plan_and_layers(seed, monkeypatch):
    """Refits whose cut areas miss the truth by ``a h^2 + b / L^2 + c h^2 / L^2`` (random a, b, c,
    h; the layers from the floor's thickness) extrapolate to the truth through with_plan_and_layers'
    four corners, each refit built at the corner's element size and layers; the plan's Richardson
    alone keeps the layers' share; a failed refit with more layers falls back to it."""
    import refine.diagnosis.fitted as fitted_module
    from refine.solid import hole_area as ha

    rng = np.random.default_rng(seed)
    e, h, truth = _hole(seed), rng.uniform(1.0, 1.4), rng.uniform(8, 14)
    a, b, c = rng.uniform(-0.03, 0.03), rng.uniform(-0.1, 0.1), rng.uniform(-0.05, 0.05)
    local = LayeredRecipe(h)
    L = ha.layers_of(local, h)
    error = lambda h_, L_: a * h_**2 + b / L_**2 + c * h_**2 / L_**2  # noqa: E731
    f_fine = cut_fraction(local, e, h)
    scale = np.sqrt(truth * (1 + error(h, L)) / f_fine / e.area)
    fitted_e = jf.Ellipse(e.cx, e.cy, e.rx * scale, e.ry * scale, e.angle)
    seen = []

    def fake_fit(hyp, points, hold, sigma):
        h_ = hyp.h or hyp.local.h
        L_ = ha.layers_of(hyp.local, h_)
        seen.append((round(h_ / h, 6), L_))
        area = truth * (1 + error(h_, L_)) / cut_fraction(hyp.local, hyp.hole, h_)  # meshed at the fit's shape
        k = np.sqrt(area / fitted_e.area)
        return SimpleNamespace(shapes=(Hole((e.cx, e.cy), (fitted_e.rx * k, fitted_e.ry * k), e.angle),))

    monkeypatch.setattr(fitted_module, "fit", fake_fit)
    fitted = SimpleNamespace(hypothesis=FakeHole(local, e), shapes=(Hole((e.cx, e.cy), (fitted_e.rx, fitted_e.ry), e.angle),),
                             q_disc=None, q_disc_parts=None, q_disc_signed=None, q_disc_refits=None)
    monkeypatch.setattr(ha, "replace", lambda obj, **kw: SimpleNamespace(**{**vars(obj), **kw}) if isinstance(obj, SimpleNamespace)
                        else replace(obj, **kw))
    g = ha.with_plan_and_layers(fitted, None, None, 1.0)
    assert sorted(seen) == sorted([(round(np.sqrt(2), 6), L), (1.0, L + 1), (round(np.sqrt(2), 6), L + 1)])
    out = extrapolated_area(g)
    assert out["layers"] == L and out["area"] == pytest.approx(truth, rel=1e-9)
    assert out["area_plan_only"] == pytest.approx(truth * (1 + b / L**2), rel=1e-9)  # the plan's h^2 terms gone
    assert set(g.q_disc_parts) == {"plan", "layers"} and np.all(g.q_disc == np.abs(g.q_disc_signed))
    w = ha.weights(L)
    assert sum(w.values()) == pytest.approx(1.0) and sum(ha.weights(L, both=False).values()) == pytest.approx(1.0)
    failed = SimpleNamespace(**{**vars(g), "q_disc_refits": replace(g.q_disc_refits, shapes={**g.q_disc_refits.shapes,
                                                                                              "both": None})})
    assert extrapolated_area(failed)["area"] == pytest.approx(out["area_plan_only"], rel=1e-12)
