"""A solid block's hidden ellipsoidal inclusion (issue 23): the synthetic block bundle, the 3D
modulus field's regions, the inclusion hypothesis (its smooth share per cell, the Mori-Tanaka
modulus, exact derivatives through the solver) and, marked slow, the diagnosis of a block with
an inclusion drawn at random under a seed and of a sound block."""

from __future__ import annotations

import json

import numpy as np
import pytest

import jaxfem as jf
from examples.cup_holder import cup_holder

from refine.exceptions import ExperimentError, ObservationError

TINY = dict(block=(0.0, 0.0, 0.0, 8.0, 4.0, 4.0), grip=(0.3, 0.6), h_data=4 / 3, h_model=2.0, spacing=1.0,
            noise=0.002)


def tiny_bundle(cause="stiffer-region", seed=0, **kw):
    from examples.block.synthetic import BlockSetting, block_bundle

    return block_bundle(cause, seed, BlockSetting(**{**TINY, **kw}))


@pytest.fixture(scope="module")
def tiny():
    """A tiny block with a stiffer inclusion (data: 324 tet10 cells; model: 96)."""
    return tiny_bundle(seed=1)


def test_block_bundle_sees_the_surface_only_and_drives_by_the_grips(tiny):
    bundle, mesh, truth = tiny
    obs = bundle.observations
    X, roles = obs.reference, obs.roles
    on_end = (np.abs(X[:, 0]) < 1e-9) | (np.abs(X[:, 0] - 8.0) < 1e-9)
    assert (roles[on_end] == "boundary").all() and (roles[~on_end] != "boundary").all()
    lo, hi = np.zeros(3), np.array([8.0, 4.0, 4.0])
    on_face = (np.abs(X - lo) < 1e-9) | (np.abs(X - hi) < 1e-9)
    assert on_face.any(axis=1).all()  # no interior marker
    assert {"guide", "validate"} <= set(roles) and obs.displacements.shape == (2, len(X), 3)
    right = np.abs(X[:, 0] - 8.0) < 1e-9
    assert np.allclose(obs.displacements[1, right, 0], 0.6, atol=5 * 0.002)  # the grip's stroke
    assert mesh.element == "tet10" and np.isclose(mesh.volumes().sum(), 128.0)
    assert truth is not None and truth.ratio > 1 and truth.inside(np.array([truth.centre])).all()


def test_block_bundle_names_bad_settings():
    with pytest.raises(ExperimentError, match="finer than the model"):
        tiny_bundle(h_data=2.0)
    with pytest.raises(ExperimentError, match="unknown cause"):
        tiny_bundle("hole")
    with pytest.raises(ExperimentError, match="unknown face 'side'"):
        tiny_bundle(faces=("top", "side"))


def test_random_inclusions_differ_by_seed_and_stay_inside():
    from examples.block.synthetic import random_inclusion

    block = (0.0, 0.0, 0.0, 40.0, 20.0, 20.0)
    drawn = [random_inclusion(np.random.default_rng(s), block, c) for c in ("stiffer-region", "softer-region")
             for s in range(6)]
    assert len({d.centre for d in drawn[:6]}) == 6 and random_inclusion(np.random.default_rng(0), block, "none") is None
    for d in drawn:
        R = np.asarray(d.rotation)
        assert np.allclose(R.T @ R, np.eye(3)) and np.isclose(np.linalg.det(R), 1.0)
        assert (np.asarray(d.centre) - max(d.axes) > 0).all() and (np.asarray(d.centre) + max(d.axes) < block[3:]).all()
        assert 2.0 <= d.ratio <= 5.0 or 0.2 <= d.ratio <= 0.5


def test_data_graded_over_the_inclusion_hold_its_volume_closer_than_the_uniform_staircase():
    from examples.block.synthetic import BlockSetting, data_inclusion, random_inclusion

    rng = np.random.default_rng(7)
    s = BlockSetting()
    errors = []
    for seed in rng.integers(0, 1000, 3):  # inclusions drawn at random: the graded data must not be shaped for one
        truth = random_inclusion(np.random.default_rng(seed), s.block, rng.choice(["stiffer-region", "softer-region"]))
        for h in (None, 1.0):
            mesh, inside = data_inclusion(BlockSetting(h_data_inclusion=h), truth)
            v = mesh.volumes()
            assert np.isclose(v.sum(), 40.0 * 20.0 * 20.0) and mesh.element == "tet10"
            errors.append(abs(v[inside].sum() / truth.volume - 1))
            if h is not None:  # 1 mm cells where the inclusion is, the uniform 2 mm ones far from it
                near = truth.inside(mesh.centroids()) | (v < 0.2)
                assert v[truth.inside(mesh.centroids())].max() <= 1.0 / 6 + 1e-9 and v[~near].max() > 1.0
    uniform, graded = np.array(errors[0::2]), np.array(errors[1::2])
    assert (graded < 0.01).all() and graded.mean() < 0.5 * uniform.mean()


def ellipsoid_cells(mesh, centre, axes, R):
    local = (mesh.centroids() - centre) @ R
    return ((local / axes) ** 2).sum(1) <= 1.0


def test_3d_field_regions_are_summarised_by_their_moment_ellipsoid():
    from refine.solid.field import blobs, moment_ellipsoid

    mesh = jf.box(0, 0, 0, 20, 10, 10, 40, 20, 20, element="tet4")
    t = 0.4
    R = np.array([[np.cos(t), -np.sin(t), 0], [np.sin(t), np.cos(t), 0], [0, 0, 1.0]])
    centre, axes = np.array([8.0, 5.0, 5.0]), np.array([4.0, 2.5, 2.0])
    inside = ellipsoid_cells(mesh, centre, axes, R)
    c, a, V = moment_ellipsoid(mesh.centroids()[inside], mesh.volumes()[inside])
    assert np.allclose(c, centre, atol=0.05) and np.allclose(a, axes, rtol=0.05)
    assert abs(V[:, 0] @ R[:, 0]) > 0.99  # the longest axis's direction
    z = np.where(inside, 1.0, 0.0) + np.where(ellipsoid_cells(mesh, np.array([17.0, 5, 5]), np.ones(3) * 1.5,
                                                              np.eye(3)), -0.7, 0.0)
    found = blobs(mesh, z, max_regions=3)
    assert [b.sign for b in found] == [1, -1]
    assert np.allclose(found[0].centroid, centre, atol=0.05) and np.isclose(found[0].ratio, np.e)
    assert np.isclose(found[0].volume, mesh.volumes()[inside].sum())


def test_mori_tanaka_share_lies_between_the_bounds_and_is_exact_at_the_ends():
    from refine.solid.inclusion import mori_tanaka

    f = np.linspace(0, 1, 11)
    for r in (0.2, 3.0, 50.0):
        E = np.asarray(mori_tanaka(f, np.log(r), 0.3))
        assert np.isclose(E[0], 1.0) and np.isclose(E[-1], r)
        reuss, voigt = 1.0 / (1 - f + f / r), 1 + f * (r - 1)
        assert (E >= reuss - 1e-12).all() and (E <= voigt + 1e-12).all()
        assert np.all(np.diff(E) * np.sign(r - 1) > 0)


def test_ellipsoid_share_holds_its_volume_and_is_smooth_in_the_shape():
    import jax

    from refine.solid.inclusion import EllipsoidModulus, cell_size

    mesh = jf.box(0, 0, 0, 12, 8, 8, 6, 4, 4, element="tet10")
    t = 0.3
    R = np.array([[1.0, 0, 0], [0, np.cos(t), -np.sin(t)], [0, np.sin(t), np.cos(t)]])
    axes = np.array([4.0, 3.0, 2.5])
    h = cell_size(mesh)
    p = EllipsoidModulus(mesh, np.array([6.3, 4.2, 3.9]), R @ np.diag(axes) @ R.T, 0.5 * h, 0.1 * h, 0.25 * h,
                         np.log(3.0), 0.3)
    z = np.asarray(p.z0)
    share = (np.asarray(p.fraction(z)) * mesh.volumes()).sum()
    assert share == pytest.approx(4 / 3 * np.pi * axes.prod(), rel=0.01)
    s = p.shape(z)
    assert np.allclose(s.axes, axes) and np.allclose(s.centre, [6.3, 4.2, 3.9]) and np.isclose(s.ratio, 3.0)
    g = jax.grad(lambda zz: (p.fraction(zz) * mesh.volumes()).sum())(z)
    assert np.isfinite(g).all() and np.abs(g[1:4]).max() < 0.1 * np.abs(g).max()  # a shift moves little volume
    assert p.infeasibility(z) is None
    assert "semi-axis" in p.infeasibility(z - np.r_[0, 0, 0, 0, 5.0, 0, 0, 0, 0, 0] / (0.5 * h) * 0.5 * h)
    assert "leave the body" in p.infeasibility(z + np.r_[0, 20.0, 0, 0, 0, 0, 0, 0, 0, 0])


def test_inclusion_prediction_derivatives_pass_a_taylor_test(tiny):
    from refine.model.measured import MeasuredModel
    from refine.solid.inclusion import Inclusion

    bundle, mesh, truth = tiny
    model = MeasuredModel(bundle.experiment, bundle.observations, mesh=mesh)
    R = np.eye(3)
    compiled, z0 = Inclusion(model, (4.2, 2.1, 1.9), (1.6, 1.2, 1.0), tuple(map(tuple, R)), 2.5).build()
    pred, J = compiled.evaluate(z0)
    dz = np.random.default_rng(0).normal(size=z0.size) * np.r_[0.3, np.full(9, 0.1)]
    errs = []
    for eps in (1e-1, 5e-2, 2.5e-2):
        errs.append(np.abs(compiled.predict(z0 + eps * dz) - pred - eps * J @ dz).max())
    rates = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert (rates > 1.7).all(), (errs, rates)


def test_strength_vanishes_without_contrast_and_saturates_for_a_rigid_inclusion():
    from refine.solid.inclusion_profile import strength

    beta = 2 * (4 - 5 * 0.3) / (15 * 0.7)
    assert strength(500.0, 1.0, 0.3) == 0.0 and strength(500.0, 0.5, 0.3) < 0 < strength(500.0, 2.0, 0.3)
    assert np.isclose(strength(500.0, 1e9, 0.3), 500.0 / beta, rtol=1e-6)
    # benchmarks/inclusion3d.py's seed 11: fitted 349 mm3 x4.36 for the truth's 590 mm3 x2.21, alike
    assert abs(strength(348.8, 4.357, 0.3) / strength(590.07, 2.211, 0.3) - 1) < 0.01


def test_profile_interval_interpolates_crossings_and_keeps_open_ends():
    from refine.solid.inclusion_profile import ProfilePoint, interval

    rng = np.random.default_rng(3)
    lo, hi = sorted(rng.uniform(-1.0, 1.0, 2))
    mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    lr = np.linspace(mid - 2 * half, mid + 2 * half, 9)
    chi2 = 100.0 + 4.0 * ((lr - mid) / half) ** 2  # rises by 4 at lo and hi
    pts = [ProfilePoint(float(a), float(c), float(100 + 10 * a), ()) for a, c in zip(lr, chi2)]
    p = interval(list(reversed(pts)), 4.0)
    assert p.open == (False, False) and p.chi2_min == pytest.approx(100.0)
    assert np.log(p.ratio[0]) == pytest.approx(lo, abs=1e-9) and np.log(p.ratio[1]) == pytest.approx(hi, abs=1e-9)
    assert p.volume[0] == pytest.approx(100 + 10 * np.log(p.ratio[0])) and p.volume[1] == pytest.approx(100 + 10 * np.log(p.ratio[1]))
    bumped = pts[:5] + [ProfilePoint(pts[5].log_ratio, 140.0, 1e4, ())] + pts[6:]  # a refit that stopped short
    b = interval(bumped, 4.0)
    assert b.ratio == pytest.approx(p.ratio) and b.volume == pytest.approx(p.volume)
    flat = interval([ProfilePoint(a, 100.0 + 0.1 * a, 50.0, ()) for a in (0.0, 1.0, 2.0)], 4.0)
    assert flat.open == (True, True) and flat.ratio == pytest.approx((1.0, np.exp(2.0)))


def test_a_lower_profile_point_becomes_the_fit_and_the_profile_is_taken_about_it():
    from types import SimpleNamespace

    from refine.solid.inclusion_profile import ProfilePoint, interval, profiled_fit

    # a toy valley: chi2 = c + 16 (lr - m)^2 + 10 (s - lr)^2, its profile over the log ratio lr
    # c + 16 (lr - m)^2 (s refitted exactly), rising by 4 at m -+ 0.5; a fit stopped short of m
    rng = np.random.default_rng(7)
    c, m = rng.uniform(50, 150), rng.uniform(-1, 1)
    chi2 = lambda z: c + 16 * (z[0] - m) ** 2 + 10 * (z[1] - z[0]) ** 2  # noqa: E731
    fitted = lambda z: SimpleNamespace(z=np.asarray(z, float), chi2_fit=chi2(z), shapes=())  # noqa: E731
    calls = []

    def profile(f):
        calls.append(f.z[0])
        lr = f.z[0] + 0.25 * np.arange(-4, 5)
        return interval([ProfilePoint(float(a), float(chi2((a, a))), 10 + a, (a, a)) for a in lr], 4.0)

    stopped = fitted((m - 0.8, m - 1.0))
    g, prof, starts = profiled_fit(stopped, profile, lambda f, z: fitted((m, m)), log=lambda s: None)
    assert np.allclose(g.z, m) and g.chi2_fit == pytest.approx(c) and prof.chi2_min == pytest.approx(c)
    assert len(calls) == 2 and calls[1] == pytest.approx(m)  # profiled again about the new minimum
    assert np.log(prof.ratio) == pytest.approx((m - 0.5, m + 0.5)) and prof.open == (False, False)
    assert [s["start"] for s in starts] == ["fit", "profile point"] and starts[1]["point_chi2"] < starts[0]["chi2"]
    # without a restart's profile the refit joins the first profile as its lowest point
    g, prof, _ = profiled_fit(stopped, profile, lambda f, z: fitted((m, m)), max_restarts=0, log=lambda s: None)
    assert np.allclose(g.z, m) and prof.chi2_min == pytest.approx(c) and len(calls) == 3
    # a fit at its minimum is kept, profiled once; a restart that ends higher is never adopted
    g, _, starts = profiled_fit(fitted((m, m)), profile, None, log=lambda s: None)
    assert np.allclose(g.z, m) and len(starts) == 1 and len(calls) == 4
    g, _, starts = profiled_fit(stopped, profile, lambda f, z: fitted((m + 3, m)), log=lambda s: None)
    assert g is stopped and len(starts) == 1


def test_total_interval_widens_each_side_by_the_discretisation_error_in_quadrature():
    from refine.solid.inclusion_total import Discretisation, errors_between, total_interval, total_intervals

    # each side of the profile's interval is 2 statistical errors; 2 discretisation errors join it in quadrature
    assert total_interval(10.0, (7.0, 11.0), 2.0) == pytest.approx((10 - 5.0, 10 + np.hypot(1.0, 4.0)))
    assert total_interval(10.0, (7.0, 11.0), 0.0) == pytest.approx((7.0, 11.0))
    lo, hi = total_interval(2.0, (1.0, 8.0), 0.5, log=True)  # the ratio's, in its log
    assert np.log(2.0 / lo) == pytest.approx(np.hypot(np.log(2.0), 1.0)) and np.log(hi / 2.0) == pytest.approx(
        np.hypot(np.log(4.0), 1.0))
    # Richardson on a mesh sqrt 2 coarser (order 2): the change itself; the ratio's of its log
    fit, other = {"ratio": 2.0, "volume": 500.0, "strength": 300.0}, {"ratio": 3.0, "volume": 420.0, "strength": 310.0}
    e = errors_between(fit, other, np.sqrt(2.0), 2.0)
    assert e == pytest.approx({"log_ratio": np.log(1.5), "volume": 80.0, "strength": 10.0})
    prof = {"ratio": [1.5, 148.0], "volume": [450.0, 560.0], "strength": [295.0, 302.0], "open": [False, True]}
    t = total_intervals(fit, prof, Discretisation(np.sqrt(2.0), 2.0, 100, other, e, 5, 1.0))
    assert t["discretisation"] and t["ratio"][1] == 148.0 and t["ratio"][0] < 1.5  # an open end stays open
    assert t["volume"] == pytest.approx([500 - np.hypot(50, 160), 500 + np.hypot(60, 160)])
    assert t["strength"] == pytest.approx([300 - np.hypot(5, 20), 300 + np.hypot(2, 20)])
    assert total_intervals(fit, prof, None)["volume"] == prof["volume"]  # not estimated: the profile's as they are


def test_the_ratio_held_inclusion_predicts_and_differentiates_as_the_full_one(tiny):
    from refine.model.measured import MeasuredModel
    from refine.model.objective import Compiled
    from refine.solid.inclusion import Inclusion
    from refine.solid.inclusion_profile import RatioHeld

    bundle, mesh, truth = tiny
    model = MeasuredModel(bundle.experiment, bundle.observations, mesh=mesh)
    compiled, z0 = Inclusion(model, (4.2, 2.1, 1.9), (1.6, 1.2, 1.0), tuple(map(tuple, np.eye(3))), 2.5).build()
    z = np.asarray(z0) + np.r_[0.2, np.random.default_rng(1).normal(0, 0.05, 9)]
    held = Compiled(model, RatioHeld(compiled.param, float(z[0]), z[1:]))
    pred, J = compiled.evaluate(z)
    assert np.allclose(held.predict(z[1:]), pred) and np.allclose(held.jacobian(z[1:]), J[..., 1:])
    assert held.param.shape(z[1:]) == compiled.param.shape(z) and held.param.infeasibility(z[1:]) is None


def test_a_solid_body_without_a_cavity_is_diagnosed_for_an_inclusion(tmp_path, tiny):
    from refine.bundle.io import read_bundle, write_bundle
    from refine.solid.inclusion_diagnosis import InclusionConfig, body_model, fills_hull

    assert fills_hull(jf.box(0, 0, 0, 2, 1, 1, 2, 1, 1, element="tet4"))
    assert not fills_hull(cup_holder(8.0, 11.0, 8.0, 3.0, 4.0).mesh)
    (tmp_path / "b").mkdir()
    jf.write_vtu(tmp_path / "b" / "mesh.vtu", tiny[1])
    bundle = read_bundle(write_bundle(tmp_path / "b", tiny[0]))
    assert body_model(bundle, InclusionConfig()).mesh.n_cells == 4 * 2 * 2 * 6
    obs = bundle.observations
    no_validate = type(bundle)(bundle.experiment, type(obs)(obs.ids, obs.reference,
                                                              np.where(obs.roles == "validate", "guide", obs.roles),
                                                              obs.displacements), root=bundle.root)
    with pytest.raises(ObservationError, match="no validate point"):
        body_model(no_validate, InclusionConfig())


def test_the_command_lines_solid_path_sends_a_block_to_the_engine_and_a_cup_holder_to_its_wall(tmp_path, tiny,
                                                                                                monkeypatch):
    from refine.bundle.io import read_bundle, write_bundle
    from refine.solid import engine, write
    from refine.solid.diagnose import thin_wall_reason

    (tmp_path / "b").mkdir()
    jf.write_vtu(tmp_path / "b" / "mesh.vtu", tiny[1])
    bundle = read_bundle(write_bundle(tmp_path / "b", tiny[0]))
    assert "thin wall" in thin_wall_reason(bundle)  # a block is no wall inside a rim
    calls = []

    class Done:
        def write(self, out):
            calls.append(out)

        def summary(self):
            return ""

        def report(self):
            return {"schema": 2}

    monkeypatch.setattr(engine, "diagnose_body", lambda b, cfg=None, log=print: Done())
    d, rep = write.diagnose_and_write(bundle, tmp_path / "out", quiet=True)
    assert calls == [tmp_path / "out"] and rep == {"schema": 2}


def diagnosed(tmp_path, cause, seed):
    from refine.bundle.io import read_bundle
    from refine.solid import diagnose_solid, report
    from examples.block.synthetic import write_block_bundle

    root, truth = write_block_bundle(tmp_path / f"{cause}{seed}", cause=cause, seed=seed)
    d = diagnose_solid(read_bundle(root), log=lambda m: None)
    rep = report(d)
    json.dumps(rep)  # report.json's content as it is
    return d, rep, truth


@pytest.fixture(scope="module")
def stiffer(tmp_path_factory):
    """A block with a stiffer ellipsoid drawn under seed 11, diagnosed (the default settings of
    examples.block.synthetic: data tet10 at 2.0 mm with 0.01 mm noise, the model tet10 at 4 mm, the
    inclusion refitted and profiled on the box graded from 2.5 mm around it to 5 mm)."""
    return diagnosed(tmp_path_factory.mktemp("block"), "stiffer-region", 11)


@pytest.mark.slow  # a finer 3D solve for the data, a 3D field, the fits and the profile: ~12 minutes on 2 shared cores
def test_hidden_inclusion_in_a_block_is_found(stiffer):
    d, rep, truth = stiffer
    assert rep["cause"] == "stiffer-region" and rep["held_out_gain"] > 1.3
    f = rep["findings"][0]
    assert np.linalg.norm(np.subtract(f["centroid"], truth.centre)) < 0.03 * 40.0  # 3 % of the block's length
    ratio, std = f["relative_elasticity"], f["std"]["relative_elasticity"]
    assert not f["ratio_at_bound"] and abs(ratio - truth.ratio) < max(0.1 * truth.ratio, 2 * std)


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="surface points alone trade the inclusion's volume against its ratio: seed 11 "
                                       "came out 23 % small and 29 % stiffer on the graded box (within 2 standard "
                                       "errors of the ratio; its profile intervals hold the truth)")
def test_hidden_inclusion_volume_and_ratio_are_recovered(stiffer):
    d, rep, truth = stiffer
    f = rep["findings"][0]
    assert abs(f["volume"] / truth.volume - 1) < 0.2 and abs(f["relative_elasticity"] / truth.ratio - 1) < 0.1


@pytest.mark.slow
def test_hidden_inclusion_strength_is_covered_by_its_profile(stiffer):
    from refine.solid.inclusion_profile import strength

    d, rep, truth = stiffer
    f = rep["findings"][0]
    s_true = strength(truth.volume, truth.ratio, 0.3)
    assert abs(f["strength"] / s_true - 1) < 0.1
    assert f["profile"]["strength"][0] <= s_true <= f["profile"]["strength"][1]
    assert f["profile"]["ratio"][0] <= f["relative_elasticity"] <= f["profile"]["ratio"][1]


@pytest.mark.slow  # the 4 mm model's bias kept the truth out (rise 10.1, threshold 4.2); the graded box's lets it in
def test_hidden_inclusion_volume_and_ratio_lie_in_their_profile_intervals(stiffer):
    d, rep, truth = stiffer
    p = rep["findings"][0]["profile"]
    assert p["ratio"][0] <= truth.ratio <= p["ratio"][1] and p["volume"][0] <= truth.volume <= p["volume"][1]


@pytest.mark.slow  # the data, a 3D field, the inclusion fitted and profiled on a 3 mm mesh: ~12 minutes
def test_hidden_inclusion_profile_covers_the_truth_with_a_finer_fit_mesh(tmp_path):
    from dataclasses import replace

    from refine.bundle.io import read_bundle
    from refine.solid.inclusion_diagnosis import InclusionConfig, diagnose_inclusion, inclusion_report
    from examples.block.synthetic import BlockSetting, model_mesh, write_block_bundle

    setting = BlockSetting(h_data=2.5)  # as measured (benchmarks/README.md's inclusion3d, --h-fit 3)
    root, truth = write_block_bundle(tmp_path / "b", cause="stiffer-region", seed=11, setting=setting)
    cfg = InclusionConfig(fit_mesh=model_mesh(replace(setting, h_model=3.0)))
    rep = inclusion_report(diagnose_inclusion(read_bundle(root), cfg, log=lambda m: None))
    f = rep["findings"][0]
    p = f["profile"]
    assert rep["model"]["cells"] > 1500 and np.linalg.norm(np.subtract(f["centroid"], truth.centre)) < 0.03 * 40.0
    assert p["ratio"][0] <= truth.ratio <= p["ratio"][1] and p["volume"][0] <= truth.volume <= p["volume"][1]


@pytest.mark.slow  # a finer 3D solve for the data, the null test and a 3D field: ~5 minutes
def test_sound_block_gives_no_finding(tmp_path):
    d, rep, truth = diagnosed(tmp_path, "none", 12)
    assert truth is None and rep["cause"] == "none" and rep["findings"] == []


@pytest.mark.slow  # the data, a 3D field, the fits and the profile (refitted once from its lowest point): ~25 minutes
@pytest.mark.xfail(strict=True, reason="the graded box's bias on a softer inclusion: refitted from its profile's "
                                       "lowest point, seed 13 fits 0.243 (truth 0.384) with 69 % of the volume, "
                                       "interval 0.054-0.340; the profile rises by 10.8 at the truth's ratio "
                                       "(threshold 4.55) and the truth's own shape lies 107 above the fit "
                                       "(benchmarks/inclusion3d.py, seed 13)")
def test_softer_inclusion_ratio_lies_in_its_profile_interval(tmp_path):
    d, rep, truth = diagnosed(tmp_path, "softer-region", 13)
    assert rep["cause"] == "softer-region"
    p = rep["findings"][0]["profile"]
    assert p["ratio"][0] <= truth.ratio <= p["ratio"][1] and p["volume"][0] <= truth.volume <= p["volume"][1]
