"""Restarts of a region or hole fit from its fitted centre (refine.diagnosis.restarts): which
shapes they start from, and that the fit with the lowest misfit is kept (the fits here are
stand-ins with a misfit of their start; benchmarks/error_coverage.py measures real ones)."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pytest

import refine.diagnosis.fitted as fitted_module
from refine.diagnosis.restarts import RESTARTS, best_of_restarts, restart_shapes
from refine.diagnosis.shapes import Hole, RegionShape


def test_a_recentred_restart_is_the_start_outline_at_the_fitted_centre_with_the_fitted_ratio():
    start = RegionShape((40.0, 30.0), (8.0, 5.0), 0.3, "ellipse", 6.0)
    fitted = RegionShape((43.0, 28.0), (10.0, 4.0), -0.2, "ellipse", 12.0)
    [s] = restart_shapes("recentred", [start], [fitted])
    assert s.centre == (43.0, 28.0) and s.axes == (8.0, 5.0) and s.angle == 0.3 and s.ratio == 12.0
    assert s.kind == "ellipse"


def test_a_round_restart_keeps_the_fitted_area_and_a_hole_stays_a_hole():
    fitted = Hole((43.0, 28.0), (9.0, 4.0), 0.5)
    [s] = restart_shapes("round", [Hole((40.0, 30.0), (6.0, 6.0), 0.0)], [fitted])
    assert isinstance(s, Hole) and s.centre == (43.0, 28.0)
    assert np.pi * s.axes[0] * s.axes[1] == pytest.approx(np.pi * 9.0 * 4.0)
    rect = RegionShape((1.0, 2.0), (4.0, 1.0), 0.1, "rectangle", 3.0)
    [r] = restart_shapes("round", [rect], [rect])
    assert r.kind == "rectangle" and r.axes == (2.0, 2.0) and r.ratio == 3.0
    with pytest.raises(ValueError, match="unknown restart"):
        restart_shapes("sideways", [rect], [rect])


@dataclass(frozen=True)
class _Hypothesis:
    remeshable = True
    element = "tri3"
    shapes: tuple = ()

    def at(self, shapes, element):
        return _Hypothesis(tuple(shapes))


@dataclass(frozen=True)
class _Model:
    h: float = 2.0


@dataclass(frozen=True)
class _Fit:
    hypothesis: _Hypothesis
    shapes: tuple
    chi2_fit: float
    sigma: float = 0.02
    model: _Model = _Model()


def _stand_in(misfit):
    """A fit that settles where it starts, with misfit ``misfit(shape)`` (raises where None)."""
    tried = []

    def fit(hypothesis, fit_mask, hold_mask, sigma):
        tried.append(hypothesis.shapes)
        chi2 = misfit(hypothesis.shapes[0])
        if chi2 is None:
            raise RuntimeError("nonlinear solve failed")
        return _Fit(hypothesis, hypothesis.shapes, chi2)

    return fit, tried


def test_the_restart_with_the_lowest_misfit_is_kept(monkeypatch):
    start = RegionShape((40.0, 30.0), (9.0, 9.0), 0.0, "ellipse", 9.0)
    first = _Fit(_Hypothesis(), (RegionShape((41.0, 31.0), (12.0, 4.0), 0.0, "ellipse", 4.0),), 75.0)
    fit, tried = _stand_in(lambda s: 60.0 if s.axes == (9.0, 9.0) else 70.0)
    monkeypatch.setattr(fitted_module, "fit", fit)
    best = best_of_restarts(first, [start], None, None)
    assert best.chi2_fit == 60.0 and best.shapes[0].centre == (41.0, 31.0)
    assert len(tried) == len(RESTARTS)


def test_a_restart_that_fails_or_misfits_more_leaves_the_first_fit(monkeypatch):
    start = RegionShape((40.0, 30.0), (8.0, 8.0), 0.0, "ellipse", 9.0)
    first = _Fit(_Hypothesis(), (RegionShape((44.0, 31.0), (12.0, 4.0), 0.0, "ellipse", 16.0),), 75.0)
    fit, tried = _stand_in(lambda s: None if s.axes == (8.0, 8.0) else 88.0)
    monkeypatch.setattr(fitted_module, "fit", fit)
    assert best_of_restarts(first, [start], None, None) is first
    assert len(tried) == 2


def test_a_restart_where_the_fit_already_is_is_not_fitted(monkeypatch):
    # the fit stayed at its start and is nearly round: neither restart at its size would start elsewhere
    shape = RegionShape((40.0, 30.0), (8.0, 7.9), 0.0, "ellipse", 9.0)
    first = _Fit(_Hypothesis(), (replace(shape, centre=(40.1, 30.0)),), 75.0)
    fit, tried = _stand_in(lambda s: 1.0)
    monkeypatch.setattr(fitted_module, "fit", fit)
    assert best_of_restarts(first, [shape], None, None, ("recentred", "round")) is first and tried == []


def test_a_hole_is_refitted_from_its_restarts_only_where_asked(monkeypatch):
    import refine.diagnosis.holes as holes

    start, settled = Hole((40.0, 30.0), (7.0, 5.0), 0.0), Hole((43.0, 28.0), (9.0, 4.0), 0.5)
    tried = []

    def fit(hypothesis, fit_mask, hold_mask, sigma):  # the first fit settles at ``settled``
        shape = hypothesis.shapes[0]
        tried.append(shape)
        if shape == start:
            return _Fit(hypothesis, (settled,), 80.0)
        return _Fit(hypothesis, (shape,), 60.0 if shape.axes[0] == shape.axes[1] else 90.0)

    monkeypatch.setattr(holes, "_subset", lambda base: None)
    monkeypatch.setattr(holes, "hole_hypothesis", lambda base, shape, h=None, element="tri3": _Hypothesis((shape,)))
    monkeypatch.setattr(holes, "fit", fit)
    monkeypatch.setattr(fitted_module, "fit", fit)
    assert holes.fit_hole(None, start, None, None, 0.02).chi2_fit == 80.0 and len(tried) == 1
    best = holes.fit_hole(None, start, None, None, 0.02, restarts=RESTARTS)
    assert best.chi2_fit == 60.0 and isinstance(best.shapes[0], Hole) and best.shapes[0].centre == settled.centre
    assert len(tried) == 1 + 1 + 2  # recentred and round: the valley's restarts need a ratio


def test_restarts_along_the_valley_keep_the_strength_and_stop_at_a_rigid_region():
    from refine.diagnosis.restarts import VALLEY_STEP
    from refine.diagnosis.valley import contrast

    fitted = RegionShape((43.0, 28.0), (10.0, 7.5), 0.3, "ellipse", 4.0)
    r = np.sqrt(75.0)
    for kind, scale in (("larger", VALLEY_STEP), ("smaller", 1 / VALLEY_STEP)):
        [s] = restart_shapes(kind, [fitted], [fitted])
        assert s.centre == fitted.centre and s.axes[0] == s.axes[1] == pytest.approx(scale * r)
        assert s.axes[0] ** 2 * contrast(s.ratio) == pytest.approx(r**2 * contrast(4.0))  # the same strength
    assert restart_shapes("larger", [fitted], [fitted])[0].ratio < 4.0 < restart_shapes("smaller", [fitted], [fitted])[0].ratio
    soft = replace(fitted, ratio=0.3)
    assert 0 < restart_shapes("smaller", [soft], [soft])[0].ratio < 0.3 < restart_shapes("larger", [soft], [soft])[0].ratio
    stiff = replace(fitted, ratio=16.0)  # 1.3225 x (15 / 17) > 1: no ratio makes a smaller one as strong
    assert restart_shapes("smaller", [stiff], [stiff]) is None
    hole = Hole((43.0, 28.0), (9.0, 4.0), 0.5)
    assert restart_shapes("larger", [hole], [hole]) is None and restart_shapes("smaller", [hole], [hole]) is None


def test_restarts_fitted_side_by_side_keep_the_same_one(monkeypatch):
    from concurrent.futures import ThreadPoolExecutor

    start = RegionShape((40.0, 30.0), (9.0, 9.0), 0.0, "ellipse", 9.0)
    first = _Fit(_Hypothesis(), (RegionShape((41.0, 31.0), (12.0, 4.0), 0.0, "ellipse", 4.0),), 75.0)
    fit, tried = _stand_in(lambda s: 60.0 if s.axes[0] > s.axes[1] - 1e-9 and s.centre == (41.0, 31.0) else 70.0)
    monkeypatch.setattr(fitted_module, "fit", fit)
    alone = best_of_restarts(first, [start], None, None)
    with ThreadPoolExecutor(2) as pool:
        together = best_of_restarts(first, [start], None, None, pool=pool)
    assert together.shapes == alone.shapes and together.chi2_fit == alone.chi2_fit == 60.0
    assert len(tried) == 2 * len(RESTARTS)
