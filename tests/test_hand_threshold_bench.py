"""benchmarks/hand.py's threshold section (benchmarks/_hand_threshold.py, _threshold_mesh.py) on
small generated curves: the scoring with one rule for truth and estimate, the analysis rerun from
its own JSON, and the Richardson step of the mesh study."""

import importlib
import json
import sys
from pathlib import Path

import numpy as np
import pytest

BENCH = Path(__file__).resolve().parents[1] / "benchmarks"


@pytest.fixture(scope="module")
def bench():
    """(``_hand_threshold``, ``_threshold_mesh``) imported from benchmarks/."""
    sys.path.insert(0, str(BENCH))
    try:
        yield importlib.import_module("_hand_threshold"), importlib.import_module("_threshold_mesh")
    finally:
        sys.path.remove(str(BENCH))
        for name in ("_hand_threshold", "_threshold_mesh"):
            sys.modules.pop(name, None)


def _detection(fraction, rise, p=1e-6, half=0.03):
    return fraction, (fraction - half, fraction + half), rise, p


def test_a_truth_without_threshold_is_met_by_estimates_that_find_none(bench):
    ht, _ = bench
    none = [_detection(0.3, 1.05), _detection(0.9, 1.2), _detection(0.5, 3.0, p=0.2)]  # rise or p too small
    some = [_detection(0.5, 1.6), _detection(0.82, 2.0)]
    score = ht._score(none + some, 0.5, has=False)
    assert score["share_agreeing"] == pytest.approx(3 / 5) and score["coverage"] is None
    assert score["share_with_threshold"] == pytest.approx(2 / 5)
    unreadable = [(np.nan, (np.nan, np.nan), np.nan, np.nan)]
    assert ht._score(none + unreadable, 0.5, has=False)["share_agreeing"] == pytest.approx(3 / 4)


def test_a_truth_with_threshold_is_met_only_within_5_percent_and_the_interval_counts_for_coverage(bench):
    ht, _ = bench
    found = [_detection(0.62, 1.6), _detection(0.70, 1.6, half=0.02), _detection(0.56, 1.6, half=0.1),
             _detection(0.6, 1.1)]  # near and a threshold / far / near (4 %) / near but no threshold by the rule
    score = ht._score(found, 0.6, has=True)
    assert score["share_agreeing"] == pytest.approx(2 / 4) and score["coverage"] == pytest.approx(2 / 4)
    assert score["hinge_share_within_5pct"] == pytest.approx(3 / 4) and score["hinge_coverage"] == pytest.approx(3 / 4)


def _data(rng, ht, n=13, dense=17, angles=3):
    """A :func:`curve_data`-like dict of one motion whose curve speeds up 2x at a random place
    (fine: ``dense`` steps, coarse: ``n`` steps, 4 facets, the maximum on one) and random Jacobians."""
    f0 = rng.uniform(0.6, 0.85)
    curve = lambda x: 0.002 * x + 0.002 * np.maximum(x - f0 * 50.0, 0.0)  # noqa: E731
    xf, x = np.linspace(0, 50.0, dense + 1), np.linspace(0, 50.0, n + 1)
    J = rng.normal(0, 1.0, (n + 1, 2, angles)) * np.array([0.5, 0.002])[None, :, None]
    h = np.radians(ht.STEP_DEG)
    skin = lambda s: s[..., None] * np.array([1.0, 0.5, 0.2, 0.1])  # noqa: E731 - facet 0 holds the maximum
    return {"step_deg": np.array(ht.STEP_DEG), "fine/centres": np.eye(4, 3), "coarse/centres": np.eye(4, 3),
            "fine/elements": np.array(9), "coarse/elements": np.array(4),
            "m/fine_x": xf, "m/fine_skin": skin(curve(xf)), "m/coarse_x": x, "m/coarse_skin": skin(curve(x)),
            "m/perturbed_x": x[:, None] + h * J[:, 0], "m/perturbed_skin": skin(curve(x)[:, None] + h * J[:, 1])}, f0


def test_the_analysis_reruns_from_its_own_json_with_the_same_figures(bench, monkeypatch):
    ht, _ = bench
    monkeypatch.setattr(ht, "DRAWS", 20)
    monkeypatch.setattr(ht, "ANGLE_SWEEP", (0.3,))
    from jaxfem.hand import Box
    data, f0 = _data(np.random.default_rng(5), ht)
    first = ht.threshold_truth(data, {"m": Box((-2.0, -2.0, -2.0), (2.0, 2.0, 2.0))})
    assert first["m"]["truth_has_threshold"] and abs(first["m"]["truth_fraction"] - f0) < 0.03
    again = ht.threshold_truth(*ht.curves_from_json(json.loads(json.dumps(first, default=float))))
    for key in ("truth_fraction", "truth_rise", "coarse_noise_free_fraction"):
        assert again["m"][key] == pytest.approx(first["m"][key], rel=1e-9)
    for key in ("share_agreeing", "coverage", "hinge_share_within_5pct"):  # Jacobians rounded to 1e-6 per degree
        assert again["m"]["tracked"][key] == pytest.approx(first["m"]["tracked"][key], abs=0.1)


def test_richardson_recovers_a_known_limit_and_declines_outside_the_asymptotic_range(bench):
    _, tm = bench
    n = np.array([2412, 4248, 12420])
    for p, limit in ((1.0, 0.8), (2.0, 0.65), (3.0, 0.74)):
        f = limit + 40.0 * (n ** (-1 / 3)) ** p
        ext = tm.extrapolated(n, f)
        assert ext["limit"] == pytest.approx(limit, abs=1e-6) and ext["order"] == pytest.approx(p, rel=1e-4)
    assert tm.extrapolated(n, [0.9, 0.8, 0.85])["limit"] is None  # turns back
    assert tm.extrapolated(n, [0.9, 0.88, 0.8])["limit"] is None  # the change grows


def test_the_targets_read_the_finest_truth_and_the_longer_motions_apart(bench):
    ht, _ = bench
    row = {"truth_fraction": 0.7, "truth_has_threshold": True, "truth_rise": 1.6, "coarse_noise_free_fraction": 0.72,
           "tracked_by_min_rise": {}, "tracked_sweep": {}, "raw": {"share_agreeing": 0.5}}
    section = lambda share: {"fine_elements": 9, "angle_noise_deg": 0.3, "strain_noise": 0.002,  # noqa: E731
                             "rule": {"min_rise": 1.25, "alpha": 0.01},
                             "m": row | {"tracked": {"share_agreeing": share, "coverage": share,
                                                     "hinge_share_within_5pct": share, "hinge_coverage": share}}}
    res = section(0.5) | {"against_finest_mesh": section(0.9), "longer": section(0.7) | {"scales": {"m": 1.5}}}
    t = ht.targets(res)
    assert t["threshold_within_5pct"]["share_agreeing"] == {"m": 0.9} and t["threshold_within_5pct"]["pass"]
    assert t["threshold_within_5pct_longer_motion"]["share_agreeing"] == {"m": 0.7}
    assert not t["threshold_within_5pct_longer_motion"]["pass"]
