"""Holes seen through DIC subsets: the subset size in the bundle (``measurement.subset``), written
by tracking and read from a DICe export; a hole hypothesis that keeps half a subset away from
every tracked point; the hole the correlated and failed subsets show (refine.diagnosis.subsets).

Geometry only (no finite-element solve): the holes, subsets and lattices are drawn at random under
a seed, and the points removed are those whose square subset meets the true hole (what a DIC code
does), so the estimate never sees the truth's outline. The mechanics of the fit are measured in
benchmarks/subset_holes.py and benchmarks/cfrp.py."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import jaxfem as jf
from refine.bundle.experiment import Experiment, RectangleDomain
from refine.bundle.io import Bundle, read_bundle, write_bundle
from refine.bundle.observations import Observations
from refine.diagnosis.subsets import (hole_from_subsets, lattice_of, seen_material, subset_distance,
                                      untracked_sites)
from refine.exceptions import ExperimentError

SAMPLE = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "dic-challenge-sample12"


def _lattice(spacing=5.0, roi=(20.0, 10.0, 120.0, 70.0)):
    xs, ys = np.meshgrid(np.arange(roi[0], roi[2] + 1e-9, spacing), np.arange(roi[1], roi[3] + 1e-9, spacing))
    return np.c_[xs.ravel(), ys.ravel()]


def _random_hole(rng, spacing):
    a, b = rng.uniform(1.5, 3.0, 2) * spacing
    return jf.Ellipse(rng.uniform(55, 85), rng.uniform(30, 50), a, b, rng.uniform(0, np.pi))


def _brute(p, hole, subset):
    """Whether p's square subset meets the hole, and the distance from p to the hole grown by the
    square (the Minkowski sum), both by dense sampling of the two outlines."""
    t = np.linspace(0, 2 * np.pi, 2000, endpoint=False)
    cx, cy, a, b, ang = hole.params
    c, s = np.cos(ang), np.sin(ang)
    ring = np.c_[cx + a * np.cos(t) * c - b * np.sin(t) * s, cy + a * np.cos(t) * s + b * np.sin(t) * c]
    r = subset / 2
    u = np.linspace(-r, r, 201)
    square = p + np.concatenate([np.c_[u, -r + 0 * u], np.c_[u, r + 0 * u], np.c_[-r + 0 * u, u], np.c_[r + 0 * u, u]])
    meets = hole.contains(square).any() or (np.abs(ring - p) <= r).all(axis=1).any()
    grown = (ring[:, None, :] + (square - p)[None, ::4, :]).reshape(-1, 2)
    return meets, float(np.min(np.hypot(*(grown - p).T)))


def test_the_grown_ellipse_distance_matches_a_dense_sampling():
    rng = np.random.default_rng(11)
    for _ in range(30):
        hole, subset = _random_hole(rng, 5.0), rng.uniform(5, 15)
        p = np.array([hole.cx, hole.cy]) + rng.uniform(-25, 25, 2)
        fast = subset_distance(p[None], hole.params, subset)[0]
        meets, distance = _brute(p, hole, subset)
        if abs(fast) > 0.02 * subset:
            assert meets == (fast < 0)
        if fast > 0:
            assert fast == pytest.approx(distance, abs=0.01 * subset)


def test_seen_material_holds_every_subsets_outline_or_the_points_alone():
    pts = _lattice()[:7]
    assert np.array_equal(seen_material(pts, None), pts)
    seen = seen_material(pts, 4.0)
    for p in pts:
        mine = seen[np.max(np.abs(seen - p), axis=1) <= 2.0 + 1e-9]
        assert {(-2.0, -2.0), (2.0, 2.0), (-2.0, 2.0), (2.0, -2.0)} <= {tuple(v) for v in np.round(mine - p, 9)}
        assert np.allclose(np.max(np.abs(mine - p), axis=1)[np.any(mine != p, axis=1)], 2.0)


def test_the_lattice_and_its_gaps_are_found_from_the_points():
    rng = np.random.default_rng(3)
    pts = _lattice()
    hole = _random_hole(rng, 5.0)
    gone = subset_distance(pts, hole.params, 9.0) <= 0
    lattice = lattice_of(pts[~gone])
    assert lattice is not None and np.allclose(lattice.step, 5.0)
    gaps = untracked_sites(lattice)
    assert {tuple(v) for v in np.round(gaps, 9)} == {tuple(v) for v in np.round(pts[gone], 9)}
    assert lattice_of(pts + rng.normal(0, 0.3, pts.shape)) is None  # scattered points: no lattice, no evidence
    assert hole_from_subsets(pts + rng.normal(0, 0.3, pts.shape), 9.0, (hole.cx, hole.cy), 20.0) is None


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_the_subsets_put_a_hole_between_the_correlated_and_the_failed(seed):
    """A random hole and subset (1.2-2.5 spacings): the ellipse from the subsets alone has the
    hole's area within 10 % and its centre within 2 % of the region's width; the points' gap, grown
    into the ring of failed subsets, is far larger (what a fit to the points alone would fill)."""
    rng = np.random.default_rng(100 + seed)
    spacing = 5.0
    pts = _lattice(spacing)
    hole, subset = _random_hole(rng, spacing), rng.uniform(1.2, 2.5) * spacing
    kept = pts[subset_distance(pts, hole.params, subset) > 0]
    guess = (hole.cx + rng.uniform(-3, 3), hole.cy + rng.uniform(-3, 3))
    evidence = hole_from_subsets(kept, subset, guess, max(hole.rx, hole.ry) + subset + spacing)
    cx, cy, a, b, _ = evidence.params
    assert a * b / (hole.rx * hole.ry) == pytest.approx(1.0, abs=0.10)
    assert np.hypot(cx - hole.cx, cy - hole.cy) < 2.0  # 2 % of the 100-mm region's width
    assert evidence.misclassified <= 2
    nearest = np.min(np.hypot(*(kept - [hole.cx, hole.cy]).T))
    assert nearest > min(hole.rx, hole.ry) + 0.5 * subset - 1e-9  # the ring a points-only hole grows into


def _experiment(**kw):
    return Experiment(name="s", kind="plane-stress", domain=RectangleDomain(20.0, 10.0, 120.0, 70.0),
                      law="neo-hookean", E=1.0, nu=0.3, **kw)


def test_the_subset_size_is_an_optional_bundle_field(tmp_path):
    pts = _lattice(10.0)
    obs = Observations(ids=np.arange(1, len(pts) + 1), reference=pts, roles=np.full(len(pts), "guide"),
                       displacements=np.zeros((1, len(pts), 2)))
    write_bundle(tmp_path / "old", Bundle(_experiment(), obs))
    assert "subset" not in (tmp_path / "old" / "experiment.toml").read_text()
    assert read_bundle(tmp_path / "old").experiment.subset is None  # older bundles: unknown, as before
    write_bundle(tmp_path / "new", Bundle(_experiment(subset=10.5), obs))
    assert read_bundle(tmp_path / "new").experiment.subset == 10.5
    for bad in (0.0, -3.0, "21"):
        with pytest.raises(ExperimentError, match="measurement.subset"):
            _experiment(subset=bad)
    toml = (tmp_path / "new" / "experiment.toml").read_text().replace("subset", "subsett")
    (tmp_path / "new" / "experiment.toml").write_text(toml)
    with pytest.raises(Exception, match="measurement.subset"):  # a typo names the key
        read_bundle(tmp_path / "new")


def test_tracks_carry_their_subset_into_the_bundle_in_length_units():
    from refine.bundle.from_tracks import ModelSkeleton, bundle_from_tracks
    from tracking import Tracks

    pts = _lattice(10.0, (0.0, 0.0, 60.0, 40.0))
    n = len(pts)
    index = np.c_[(pts[:, 1] / 10).astype(int), (pts[:, 0] / 10).astype(int)]
    positions = np.stack([pts, pts + 0.5])
    tracks = Tracks(ids=np.arange(1, n + 1), reference=pts, positions=positions, lost=np.zeros((2, n), bool),
                    quality=np.ones((2, n)), grid_index=index, meta={"subset_px": 21})
    bundle, _ = bundle_from_tracks(tracks.to_length(0.05), "t", ModelSkeleton())
    assert bundle.experiment.subset == pytest.approx(1.05)
    bundle, _ = bundle_from_tracks(replace(tracks, meta={}).to_length(0.05), "t", ModelSkeleton())
    assert bundle.experiment.subset is None  # a grid tracker or a CSV export: unknown


@pytest.mark.skipif(not SAMPLE.exists(), reason="../shared/data/dic-challenge-sample12 is absent")
def test_a_dice_export_gives_its_subset_size():
    from tracking import read_dice

    assert read_dice(SAMPLE / "dice-solution").meta["subset_px"] == 27.0


def _tracked_around_a_hole(rng, spacing: float, subset: float):
    """A lattice of ``spacing`` with a random hole whose failed subsets (square side ``subset``) are
    removed, as :class:`Observations` (the lattice's outer rows and columns the boundary) and the hole."""
    pts = _lattice(spacing)
    hole = _random_hole(rng, spacing)
    keep = subset_distance(pts, hole.params, subset) > 0
    edge = (pts[keep, 0] % 100 == 20) | (pts[keep, 1] % 60 == 10)
    obs = Observations(ids=np.flatnonzero(keep) + 1, reference=pts[keep], roles=np.where(edge, "boundary", "guide"),
                       displacements=np.zeros((1, keep.sum(), 2)))
    return obs, hole


def test_a_hole_keeps_half_a_subset_from_every_tracked_point():
    """With the subset known, the hole's start is free of every tracked point's square and a step
    that would cover one is infeasible; without it only the points themselves are kept out."""
    from refine.diagnosis.holes import hole_hypothesis, subset_start
    from refine.diagnosis.shapes import Hole
    from refine.model.measured import MeasuredModel

    spacing, subset = 5.0, 9.0
    obs, hole = _tracked_around_a_hole(np.random.default_rng(5), spacing, subset)
    gap = Hole((hole.cx, hole.cy), (max(hole.rx, hole.ry) + 6, max(hole.rx, hole.ry) + 6), 0.0)
    with_subset = MeasuredModel(_experiment(subset=subset), obs, h=4.0)
    start = hole_hypothesis(with_subset, subset_start(with_subset, gap)).hole
    assert subset_distance(obs.reference, start.params, subset).min() > 0
    assert start.rx * start.ry > 0.8 * hole.rx * hole.ry
    compiled, _ = hole_hypothesis(with_subset, subset_start(with_subset, gap)).build()
    grow = np.zeros(compiled.param.size)
    grow[2:4] = 0.3 * subset / compiled.param.scale  # both axes 2.7 mm longer: into the nearest squares, short of the points
    assert "tracked point" in compiled.param.infeasibility(grow)
    points_only = MeasuredModel(_experiment(), obs, h=4.0)
    plain = hole_hypothesis(points_only, gap).hole
    assert plain.rx * plain.ry > start.rx * start.ry  # today's start fills the ring


def test_a_hole_fitted_with_a_law_starts_where_the_subsets_put_it(monkeypatch):
    """``fit_hole_with_law`` (a hole and a material law fitted together) starts, like ``fit_hole``,
    from the subsets' ellipse: from a candidate off the hole's centre it starts on the hole, clear of every
    tracked square (the candidate only shrunk clear of the squares was too small to be tried). The fit itself is replaced by a stub that hands back the hypothesis."""
    from refine.diagnosis import hole_law
    from refine.diagnosis.fitted import NotApplicable
    from refine.diagnosis.holes import hole_hypothesis
    from refine.diagnosis.shapes import Hole
    from refine.model.measured import MeasuredModel

    spacing, subset = 5.0, 9.0
    obs, hole = _tracked_around_a_hole(np.random.default_rng(17), spacing, subset)
    r = max(hole.rx, hole.ry) + 4
    off = Hole((hole.cx + 0.6 * r, hole.cy - 0.3 * r), (r, r), 0.0)   # a candidate off the hole's centre
    base = MeasuredModel(_experiment(subset=subset), obs, h=4.0)

    class Started(Exception):
        pass

    def stub(hypothesis, *args, **kwargs):
        raise Started(hypothesis)

    monkeypatch.setattr(hole_law, "fit", stub)
    with pytest.raises(Started) as caught:
        hole_law.fit_hole_with_law(base, off, "fibre-reinforced", None, None, 0.02,
                                   start={"fibre_angle": 0.3, "fibre_stiffness": 2.0})
    start = caught.value.args[0].hole
    assert subset_distance(obs.reference, start.params, subset).min() > 0
    assert np.hypot(start.cx - hole.cx, start.cy - hole.cy) < 0.25 * spacing
    assert start.rx * start.ry > 0.8 * hole.rx * hole.ry
    with pytest.raises(NotApplicable):  # the start before: the candidate shrunk clear of the squares, too small
        hole_hypothesis(base, off)
