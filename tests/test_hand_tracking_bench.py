"""benchmarks/hand.py's tracking section (benchmarks/_hand_tracking.py) on made-up runs: a
noise-limited way of tracking (the markers alone) judged by its reported uncertainty with the
1-degree figure kept beside, the other ways by 1 degree, and a rerun of some ways of a seed
(``--kinds``) merged without losing the others."""

import numpy as np
import pytest

from tests._bench import benchmark_modules


@pytest.fixture(scope="module")
def ht():
    with benchmark_modules("_hand_tracking") as (mod,):
        yield mod


def _way(rng, err, p=None):
    """A made-up run of one way of tracking: largest error ``err`` (degrees), chi-square tail ``p``."""
    e = rng.uniform(-err, err, (5, 5))
    e.flat[rng.integers(25)] = err
    row = {"max_abs_error_deg": float(np.abs(e).max()), "angle_error_deg": e.tolist(),
           "max_abs_error_deg_per_angle": {}, "per_frame": {"max_abs_error_deg": err, "angle_error_deg": e.tolist()},
           "within_2_std": 0.9, "released": [False] * 5, "s_per_frame": 10.0, "strain_rms_area": [0.01]}
    return row if p is None else row | {"chi2": 30.0, "chi2_dof": 25, "chi2_p": p}


def _runs(rng, marker_p, marker_err=1.2):
    return [{"seed": s, "strain_floor": {"rms_area": [0.01]}, "clouds": _way(rng, 0.5),
             "markers": _way(rng, marker_err if s == 2 else 0.4, marker_p[s]), "both": _way(rng, 0.3)} for s in range(3)]


def test_markers_alone_are_judged_by_their_reported_uncertainty_the_degree_kept_beside(ht):
    rng = np.random.default_rng(4)
    t = ht.targets({"runs": _runs(rng, {0: 0.5, 1: 0.3, 2: 0.2})})
    row = t["joint_angles_within_reported_error_markers"]
    assert "joint_angles_within_1_deg_markers" not in t
    assert row["pass"] is True and row["within_1_deg"] is False and row["max_abs_error_deg"] == pytest.approx(1.2)
    assert t["joint_angles_within_1_deg_clouds"]["pass"] and t["joint_angles_within_1_deg_both"]["pass"]
    low = rng.uniform(1e-6, 0.009)  # one seed's errors beyond what its uncertainty allows
    assert ht.targets({"runs": _runs(rng, {0: 0.5, 1: low, 2: 0.2}, 0.8)})[
        "joint_angles_within_reported_error_markers"]["pass"] is False
    unknown = ht.targets({"runs": _runs(rng, {0: 0.5, 1: None, 2: 0.2})})["joint_angles_within_reported_error_markers"]
    assert unknown["pass"] is None  # a run from before the chi-square was recorded: not judged


def test_a_rerun_of_some_ways_keeps_the_others_of_the_same_seed(ht):
    rng = np.random.default_rng(6)
    old = _runs(rng, {0: 0.5, 1: 0.3, 2: 0.2})
    new = [{"seed": 1, "strain_floor": {"rms_area": [0.02]}, "markers": _way(rng, 0.6, 0.4)}]
    merged = ht.merge_runs(old, new)
    assert [r["seed"] for r in merged] == [0, 1, 2]
    one = merged[1]
    assert "carried" not in one and "carried" not in one["markers"] and one["markers"] == new[0]["markers"]
    assert one["clouds"]["max_abs_error_deg"] == old[1]["clouds"]["max_abs_error_deg"] and "carried" in one["clouds"]
    assert "carried" in merged[0] and "carried" in merged[2] and merged[2]["markers"] == old[2]["markers"]
