"""The typed values of the diagnosis (shapes, findings) and the one residual function."""

from types import SimpleNamespace

import numpy as np
import pytest

from refine.bundle.experiment import RectangleDomain
from refine.diagnosis.findings import findings
from refine.diagnosis.shapes import Hole, RegionShape, report_row
from refine.measures import Residuals


def test_residuals_drop_lost_points_and_count_the_rest():
    rng = np.random.default_rng(0)
    measured = rng.normal(size=(3, 5, 2))
    measured[1, 2] = np.nan  # lost in frame 2
    points = np.array([True, True, True, False, True])
    predicted = rng.normal(size=(3, 5, 2))
    at = Residuals.at(measured, points, sigma=0.5)
    r = at(predicted)
    keep = np.isfinite(measured[:, points]).all(-1)
    expected = ((predicted[:, points] - measured[:, points]) / 0.5)[keep].reshape(-1)
    np.testing.assert_array_equal(r, expected)
    assert at.n == r.size == 2 * (3 * 4 - 1)
    assert at.chi2(predicted) == pytest.approx(np.sum(expected**2), rel=1e-14)
    J = rng.normal(size=(3, 5, 2, 4))
    np.testing.assert_array_equal(at.jacobian(J), J[:, points][keep].reshape(-1, 4) / 0.5)
    np.testing.assert_array_equal(at.weighted(predicted), (predicted[:, points] / 0.5)[keep].reshape(-1))


def test_shapes_move_clamp_and_report():
    a = RegionShape((50.0, 30.0), (10.0, 5.0), 0.0, "ellipse", 4.0)
    b = RegionShape((51.0, 30.0), (10.0, 5.0), np.pi / 2, "ellipse", 4.0)
    assert a.moved(b) == pytest.approx(np.pi / 2 * 5.0)  # a quarter turn of a 10 x 5 ellipse
    assert a.cause == "stiffer-region" and RegionShape((0, 0), (1, 1), 0, "ellipse", 0.5).cause == "softer-region"
    edge = RegionShape((21.0, 30.0), (1.0, 5.0), 0.0, "rectangle", 2.0).clamped(RectangleDomain(20, 10, 120, 70), 5.0)
    assert edge.centre == (20 + 3.0 + 2.5, 30.0) and edge.axes == (3.0, 5.0) and edge.kind == "rectangle"
    hole = Hole((60.0, 40.0), (6.0, 4.0), 0.3)
    assert report_row(hole) == [60.0, 40.0, 6.0, 4.0, 0.3, 0.0] and hole.kind == hole.cause == "hole"
    assert hole.describe() == "hole at (60.0, 40.0) axes (6.0, 4.0) angle 17 deg ratio 0.00"
    assert RegionShape.of(a.geometry(), 4.0) == a


def test_findings_read_as_report_json():
    chosen = SimpleNamespace(cause="stiffer-region", law="neo-hookean", z_std=np.array([0.1, 1, 1, 1, 1, 1]),
                             shapes=(RegionShape((50.0, 30.0), (10.0, 5.0), 0.2, "ellipse", 4.0),))
    [f] = findings(chosen, "because", None)
    j = f.to_json()
    assert list(j) == ["cause", "region", "relative_elasticity", "modulus", "relative_elasticity_std", "evidence"]
    assert j["relative_elasticity_std"] == pytest.approx(0.4) and f["region"]["centroid"] == [50.0, 30.0]
    assert f.region.shape == "ellipse" and f.region.area == pytest.approx(np.pi * 50, rel=1e-6)
    law = findings(SimpleNamespace(cause="material-law", law="mooney-rivlin"), "e", None)[0].to_json()
    assert law == {"cause": "material-law", "region": None, "relative_elasticity": None, "modulus": None,
                   "law": "mooney-rivlin", "evidence": "e"}
    assert findings(SimpleNamespace(cause="none"), "e", None) == []
