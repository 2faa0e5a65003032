"""The scar benchmarks' error checks (issue 25: the relative elasticity "within its reported
uncertainty"): benchmarks/scar.py's coverage of the ratio's z over seeds, and
benchmarks/scar_error_budget.py's split of the noise by where it sits and the interval of a
standard deviation from draws. Fast: no solve (the fits themselves are what the benchmarks run)."""

from __future__ import annotations


import numpy as np
import pytest
from scipy.stats import norm



@pytest.fixture(scope="module")
def modules():
    from benchmarks import scar, scar_error_budget

    return scar, scar_error_budget


def test_coverage_passes_right_errors_and_fails_too_small_or_too_large_ones(modules):
    scar, _ = modules
    z = np.random.default_rng(7).standard_normal(300)
    right = scar.coverage(z)
    assert right["pass"] and right["n"] == 300
    assert abs(right["outside"] - right["expected_outside"]) < 3 * np.sqrt(right["expected_outside"])
    short = scar.coverage(1.4 * z)  # errors reported 1.4 times too small
    assert not short["pass"] and short["p_outside"] < 0.05 and short["p_sum_z2"] < 0.05
    wide = scar.coverage(z / 2)  # errors reported twice too large: sum z^2 far too small
    assert not wide["pass"] and wide["p_sum_z2"] < 0.05


def test_coverage_of_two_seeds_one_outside_is_the_binomial_probability(modules):
    scar, _ = modules
    c = scar.coverage([2.35, -0.82])
    p = 2 * norm.sf(2.0)
    assert c["outside"] == 1 and c["n"] == 2
    assert c["p_outside"] == pytest.approx(1 - (1 - p) ** 2, rel=1e-12)
    assert c["sum_z2"] == pytest.approx(2.35**2 + 0.82**2)


def test_noise_sources_partition_the_points_into_drive_and_fitted(modules):
    _, budget = modules
    roles = np.array(["boundary", "guide", "validate", "boundary", "guide"])
    parts = budget.noise_sources(roles)
    assert set(parts) == {"drive", "fitted"}
    assert np.array_equal(parts["drive"], roles == "boundary")
    assert not np.any(parts["drive"] & parts["fitted"]) and np.all(parts["drive"] | parts["fitted"])


def test_std_interval_holds_the_true_std_95_percent_of_the_time(modules):
    _, budget = modules
    rng = np.random.default_rng(3)
    sigma, n, trials = 0.017, 12, 2000
    hits = 0
    for _ in range(trials):
        lo, hi = budget.std_interval(float(np.std(rng.normal(0, sigma, n), ddof=1)), n)
        hits += lo <= sigma <= hi
    assert 0.93 <= hits / trials <= 0.97


@pytest.mark.slow  # a fit and five refits of a small scar (a few minutes on 2 shared cores)
def test_the_noise_split_adds_up_and_each_part_is_within_its_reported_error(modules):
    from dataclasses import replace

    from examples.skin.synthetic import SKIN, random_scar, skin_bundle

    _, budget = modules
    setting = replace(SKIN, spacing=4.0, h=1.6)  # a coarser grid and data mesh than the benchmark's
    truth = random_scar(np.random.default_rng(11), setting)
    noisy = skin_bundle(truth, seed=11, setting=setting)
    clean = budget.final_fit(skin_bundle(truth, seed=11, setting=replace(setting, noise=0.0)), truth, setting.noise)
    split = budget.split_the_noise(noisy, clean, setting.noise, part_draws=2, seed=0)
    std = np.hypot(split["drive"]["reported_std"], split["fitted"]["reported_std"])
    assert split["drive"]["reported_std"] > 0 and split["fitted"]["reported_std"] > 0
    assert abs(split["sum_of_parts"] - split["whole"]) < 0.1 * std, split  # linear in the noise at this level
    for part in ("drive", "fitted"):
        assert abs(split[part]["z"]) < 4, split
        assert len(split[part]["draws"]) == 2 and split[part]["draws_std"] > 0


def test_within_reported_uncertainty_judges_the_seeds_together_keeping_each_seeds_z(modules):
    scar, _ = modules
    rng = np.random.default_rng(25)
    z = rng.standard_normal(40)
    z[[3, 17]] = [2.3, -2.1]  # two seeds beyond 2 errors of 40: ordinary where the errors are right
    rows = [{"seed": s, "ratio_z": v} for s, v in enumerate(z)]
    t = scar.within_reported_uncertainty(rows)
    assert t["pass"] and t["seeds_outside"] == sorted(np.flatnonzero(np.abs(z) > 2).tolist())
    assert t["value"] == pytest.approx(np.mean(np.abs(z) <= 2)) and t["value"] < 1  # a per-seed target fails here
    assert t["z"]["3"] == pytest.approx(2.3) and len(t["z"]) == 40
    short = scar.within_reported_uncertainty([{"seed": s, "ratio_z": 1.6 * v} for s, v in enumerate(z)])
    assert not short["pass"] and short["p_sum_z2"] < 0.05  # errors 1.6 times too small


def test_summary_states_the_2_error_target_over_seeds_and_the_5_percent_one_per_seed(modules):
    scar, _ = modules
    pocket = {"median_inside": 0.03, "median_outside": 0.1, "lowest_decile_on_scar": 1.0}
    rows = [{"seed": s, "named": True, "ratio_error": e, "ratio_z": z, "ratio_z_std": z, "centroid_error": 3e-4,
             "ratio_within_5_percent": abs(e) <= 0.05, "centroid_within_2_percent": True, "pocket": pocket,
             "diagnose_seconds": 100.0} for s, (e, z) in enumerate([(0.01, 2.4), (-0.002, -0.3), (0.06, 0.9)])]
    targets = scar.summarise(rows, None)["targets"]
    assert targets["ratio_within_5_percent"]["value"] == pytest.approx(2 / 3)
    assert not targets["ratio_within_5_percent"]["pass"]  # per seed: seed 2 is 6 % off
    two = targets["ratio_within_2_std"]
    assert two["seeds_outside"] == [0] and two["n"] == 3 and two["outside"] == 1
    assert two["pass"] == (two["p_outside"] >= 0.05 and two["p_sum_z2"] >= 0.05)
    assert "ratio_errors_consistent_with_reported" not in targets  # folded into ratio_within_2_std


def test_noise_free_summary_counts_errors_within_their_estimates_per_shape_kind(modules):
    _, budget = modules
    rows = [{"shape": "Ellipse", "error": e, "estimate": d, "error_over_estimate": abs(e) / d, "std": 0.03}
            for e, d in [(0.0055, 0.0027), (-0.0019, 0.0013), (0.001, 0.002)]]
    rows.append({"shape": "Rect", "error": 0.0092, "estimate": 0.0088, "error_over_estimate": 0.0092 / 0.0088,
                 "std": 0.017})
    s = budget.noise_free_summary(rows)
    ellipse = s["by_shape"]["Ellipse"]
    assert ellipse["n"] == 3 and ellipse["within_1"] == 1 and ellipse["within_2"] == 2
    assert ellipse["largest_excess"] == pytest.approx(0.0055 - 0.0027)
    assert ellipse["median_error_over_estimate"] == pytest.approx(0.0019 / 0.0013)
    assert s["by_shape"]["Rect"]["within_2"] == 1 and ellipse["positive"] == 2
    target = s["targets"]["noise_free_error_within_2_discretisation"]
    assert target["value"] == pytest.approx(3 / 4) and not target["pass"]


def test_coverage_sees_a_bias_in_the_mean_z(modules):
    scar, _ = modules
    z = np.random.default_rng(5).standard_normal(100)
    assert scar.coverage(z)["p_mean_z"] == pytest.approx(2 * norm.sf(abs(np.mean(z)) * 10))  # n = 100
    biased = scar.coverage(z + 0.5)  # every error half a reported error high
    assert biased["mean_z"] == pytest.approx(np.mean(z) + 0.5) and biased["p_mean_z"] < 0.05


def test_extrapolated_summary_compares_the_z_before_and_after_removing_a_one_sided_bias(modules):
    _, budget = modules
    rng = np.random.default_rng(20)
    noise = rng.standard_normal(60)
    rows = [{"z": n + 0.8, "z_corrected": n, "signed_estimate": 0.01} for n in noise]  # a bias of 0.8 errors
    s = budget.extrapolated_summary(rows)
    assert s["signed_estimate_positive"] == 60 and s["n"] == 60
    assert s["z"]["p_mean_z"] < 1e-3 and s["z_extrapolated"]["mean_z"] == pytest.approx(np.mean(noise))
    assert s["targets"]["extrapolated_ratio_within_2_std"] == s["z_extrapolated"]
