"""The discretisation term of the reported errors (refine.diagnosis.uncertainty): the total error is
the standard error and the discretisation error in quadrature, each quantity on its own, and
report.json gains ``discretisation``, ``total_std`` and ``relative_elasticity_total_std`` beside the
keys older readers know (no solve here: the fit itself is measured by benchmarks/error_coverage.py)."""

import numpy as np
import pytest

from refine.diagnosis.findings import FoundRegion, findings
from refine.diagnosis.shapes import Hole, RegionShape
from refine.diagnosis.uncertainty import (QUANTITIES, ShapeErrors, as_row, discretisation_errors, errors_of,
                                          sparser_drive, total_errors)


def _random_errors(rng, hole=False) -> ShapeErrors:
    row = rng.uniform(0.01, 2.0, len(QUANTITIES))
    return errors_of(row, Hole((0.0, 0.0), (1.0, 1.0), 0.0) if hole else RegionShape((0, 0), (1, 1), 0.0))


def test_total_error_is_both_in_quadrature_per_quantity():
    rng = np.random.default_rng(4)
    for _ in range(5):
        std, disc = _random_errors(rng), _random_errors(rng)
        total = as_row(total_errors(std, disc))
        assert np.allclose(total, np.sqrt(as_row(std) ** 2 + as_row(disc) ** 2))
        assert np.all(total >= np.maximum(as_row(std), as_row(disc)))
    one = _random_errors(rng)
    assert total_errors(one, None) is one and total_errors(None, one) is one and total_errors(None, None) is None


def test_a_hole_has_no_ratio_error_and_a_missing_term_is_not_a_zero():
    rng = np.random.default_rng(5)
    std, disc = _random_errors(rng, hole=True), _random_errors(rng, hole=True)
    assert std.relative_elasticity is None and total_errors(std, disc).relative_elasticity is None
    row = as_row(_random_errors(rng))
    gap = row.copy()
    gap[4] = np.nan  # e.g. an angle the coarse refit could not give
    region = RegionShape((0, 0), (1, 1), 0.0)
    t = as_row(total_errors(errors_of(row, region), errors_of(gap, region)))
    assert t[4] == pytest.approx(row[4])
    assert np.allclose(np.delete(t, 4), np.hypot(np.delete(row, 4), np.delete(gap, 4)))


class _Chosen:
    """What :func:`findings` reads of a fitted hypothesis (no model: no covariance to carry)."""

    def __init__(self, shapes, q_disc, law="neo-hookean", parts=None):
        self.shapes, self.q_disc, self.law, self.z_std, self.z_cov = shapes, q_disc, law, None, None
        self.q_disc_parts = parts
        self.hypothesis = type("H", (), {"law": law})()

    @property
    def cause(self):
        return self.shapes[0].cause


def test_report_json_gains_the_discretisation_and_total_keys_and_keeps_the_old_ones():
    rng = np.random.default_rng(6)
    shape = RegionShape(tuple(rng.uniform(10, 30, 2)), tuple(rng.uniform(3, 6, 2)), float(rng.uniform(0, 3)),
                        "rectangle", float(rng.uniform(2, 6)))
    parts = {k: rng.uniform(0.001, 0.1, (1, len(QUANTITIES))) for k in ("mesh", "drive")}
    q_disc = np.hypot(parts["mesh"], parts["drive"])
    [f] = findings(_Chosen((shape,), q_disc, parts=parts), "evidence", None)
    j = f.to_json()
    for key in ("cause", "region", "relative_elasticity", "modulus", "evidence"):
        assert key in j
    assert isinstance(f.region, FoundRegion)
    assert j["discretisation"]["relative_elasticity"] == pytest.approx(q_disc[0, 6], abs=1e-4)
    assert j["discretisation"]["centroid"] == pytest.approx(q_disc[0, :2], abs=1e-4)
    assert j["discretisation_parts"]["drive"]["axes"] == pytest.approx(parts["drive"][0, 2:4], abs=1e-4)
    # no covariance: the total is the discretisation error alone, never a silent zero
    assert j["relative_elasticity_total_std"] == pytest.approx(q_disc[0, 6], abs=1e-4)
    assert "std" not in j and "relative_elasticity_std" not in j
    [g] = findings(_Chosen((shape,), None), "evidence", None)
    assert not {"discretisation", "total_std", "relative_elasticity_total_std"} & set(g.to_json())
    assert discretisation_errors(_Chosen((shape,), None)) is None


def test_a_sparser_drive_keeps_every_other_boundary_point_along_the_outline_and_the_fitted_points():
    from refine.bundle.observations import Observations

    rng = np.random.default_rng(7)
    x0, y0 = rng.uniform(0, 5, 2)
    n = 9  # points per side of a square grid, the outer ring drives
    X, Y = np.meshgrid(x0 + 2.0 * np.arange(n), y0 + 2.0 * np.arange(n))
    ref = np.stack([X.ravel(), Y.ravel()], 1)
    ring = (X == X.min()) | (X == X.max()) | (Y == Y.min()) | (Y == Y.max())
    roles = np.where(ring.ravel(), "boundary", np.where(rng.uniform(size=n * n) < 0.2, "validate", "guide"))
    obs = Observations(np.arange(n * n), ref, roles, 0.01 * rng.standard_normal((1, n * n, 2)))
    sparse = sparser_drive(obs)
    kept = sparse.roles == "boundary"
    assert kept.sum() == (obs.roles == "boundary").sum() // 2  # 32 ring points: 16 drive
    assert np.all(sparse.mask("guide") == obs.mask("guide"))  # what is fitted is unchanged
    dropped = (obs.roles == "boundary") & ~kept
    assert np.all(sparse.roles[dropped] == "validate")
    # along the outline, kept and dropped points alternate: no two kept points are grid neighbours
    K = ref[kept]
    gaps = np.linalg.norm(K[:, None] - K[None], axis=2) + np.eye(len(K)) * 1e9
    assert gaps.min() > 2.0 + 1e-9


def test_the_summary_gives_the_ratio_with_its_standard_error_then_the_discretisation_and_total():
    from types import SimpleNamespace

    from refine.diagnosis.report import summary

    rng = np.random.default_rng(8)
    ratio, std, disc = float(rng.uniform(2, 6)), float(rng.uniform(0.01, 0.1)), float(rng.uniform(0.01, 0.1))
    finding = {"cause": "stiffer-region", "relative_elasticity": ratio, "relative_elasticity_std": std,
               "relative_elasticity_total_std": float(np.hypot(std, disc)), "modulus": None,
               "discretisation": {"relative_elasticity": disc},
               "region": {"centroid": [1.0, 2.0], "area": 3.0, "axes": [1.0, 1.0]}}
    errors = {"guide_error": 0.1, "validation_error": 0.1, "tracking_error": 0.01}
    report = {"bundle": "b", "baseline": errors, "refined": errors, "background": {"modulus": None},
              "findings": [finding], "gain": {"validation_error": 1.0}, "seconds": 1.0}
    d = SimpleNamespace(report=lambda: report, null=SimpleNamespace(ratio=9.0, p_value=1e-9),
                        bundle=SimpleNamespace(experiment=SimpleNamespace(E=1.0, law="neo-hookean")))
    text = summary(d)
    total = np.hypot(std, disc)
    assert f"{ratio:.2f} +- {std:.2f} (standard error; discretisation {disc:.2f}, total {total:.2f})" in text
    finding.pop("discretisation")
    finding.pop("relative_elasticity_total_std")
    assert f"{ratio:.2f} +- {std:.2f} x the background" in summary(d)  # an older report reads as before
    finding["relative_elasticity_std"] = float("inf")  # the valley's draws reach a rigid region
    assert f"{ratio:.2f} +- inf (the data bound it from below only) x the background" in summary(d)


def test_an_unbounded_error_is_strict_json_with_its_flag():
    import json

    from refine.diagnosis.report import _finite

    report = {"findings": [{"relative_elasticity_std": float("inf"), "relative_elasticity_bounded_below_only": True,
                            "std": {"relative_elasticity": np.inf, "axes": np.array([0.1, np.nan])}}]}
    text = json.dumps(_finite(report), allow_nan=False)  # raises on Infinity / NaN
    back = json.loads(text)["findings"][0]
    assert back["relative_elasticity_std"] is None and back["relative_elasticity_bounded_below_only"] is True
    assert back["std"] == {"relative_elasticity": None, "axes": [0.1, None]}


def test_a_signed_richardson_estimate_extrapolates_an_order_2_error_to_the_truth():
    from refine.diagnosis.shapes import RegionShape
    from refine.diagnosis.uncertainty import _richardson

    def at(h):  # a fit whose ratio errs by 0.01 h^2 (h: the element size)
        return (RegionShape((20.0, 15.0), (6.0, 4.0), 0.3, "ellipse", 3.0 + 0.01 * h**2),)

    fine, coarse = at(1.0), at(np.sqrt(2.0))
    signed = _richardson(fine, coarse, np.sqrt(2.0), 2.0, signed=True)[0, 6]
    assert signed == pytest.approx(0.01)  # the fine fit's own error, with its sign
    assert fine[0].ratio - signed == pytest.approx(3.0)  # Richardson's extrapolation
    assert _richardson(fine, coarse, np.sqrt(2.0), 2.0)[0, 6] == pytest.approx(0.01)  # unsigned as before
    low = (RegionShape((20.0, 15.0), (6.0, 4.0), 0.3, "ellipse", 2.99),)
    assert _richardson(low, (RegionShape((20.0, 15.0), (6.0, 4.0), 0.3, "ellipse", 2.98),), np.sqrt(2.0), 2.0,
                       signed=True)[0, 6] == pytest.approx(-0.01)
