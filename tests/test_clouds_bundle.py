"""Unlabelled clouds in a bundle (clouds.csv): written and read back, beside or instead of tracked
points; older bundles unaffected; malformed files and arrays give clear errors."""

from __future__ import annotations

import numpy as np
import pytest

from refine.bundle import Clouds, Observations, read_bundle, read_clouds, write_bundle
from refine.bundle.experiment import Experiment, RectangleDomain
from refine.bundle.io import Bundle
from refine.exceptions import BundleError, ObservationError


def _experiment():
    return Experiment(name="c", kind="plane-stress", domain=RectangleDomain(0.0, 0.0, 10.0, 5.0), law="neo-hookean",
                      E=10.0, nu=0.3, thickness=1.0)


def _clouds(rng, sizes=(7, 5, 9)):
    return Clouds(tuple(rng.uniform(0, 10, (n, 2)) for n in sizes))


def test_clouds_only_bundle_round_trips(tmp_path):
    rng = np.random.default_rng(0)
    clouds = _clouds(rng)
    write_bundle(tmp_path / "b", Bundle(_experiment(), None, clouds=clouds))
    assert not (tmp_path / "b" / "points.csv").exists()
    back = read_bundle(tmp_path / "b")
    assert back.observations is None and back.clouds.n_frames == 2 and back.clouds.dim == 2
    for a, b in zip(clouds.points, back.clouds.points):
        np.testing.assert_array_equal(a, b)


def test_clouds_beside_points_and_older_bundles_unaffected(tmp_path):
    ref = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 5.0], [0.0, 5.0], [5.0, 2.5]])
    obs = Observations(np.arange(1, 6), ref, ["boundary"] * 4 + ["guide"], np.full((2, 5, 2), 0.1))
    bundle = Bundle(_experiment(), obs)
    write_bundle(tmp_path / "old", bundle)
    old = read_bundle(tmp_path / "old")
    assert old.clouds is None and old.observations.n_points == bundle.observations.n_points
    clouds = _clouds(np.random.default_rng(2), (4, 6, 5))  # frames 0..2, as displacements' 1..2 and the reference
    write_bundle(tmp_path / "both", Bundle(bundle.experiment, bundle.observations, clouds=clouds))
    both = read_bundle(tmp_path / "both")
    assert both.observations.n_points == bundle.observations.n_points
    assert [len(p) for p in both.clouds.points] == [4, 6, 5]


@pytest.mark.parametrize("text, problem", [
    ("frame,x,y\n0,1,2\n2,3,4\n", "frame 1 has no point"),
    ("frame,x,y\n0,1,2\n1,nan,4\n", "NaN"),
    ("frame,x,y\n0,1,2\n1,a,4\n", "is not a number"),
    ("frame,x\n0,1\n", "header"),
    ("frame,x,y\n", "lists no points"),
    ("frame,x,y\n0,1,2\n-1,3,4\n", "negative"),
])
def test_malformed_clouds_csv_names_the_problem(tmp_path, text, problem):
    (tmp_path / "clouds.csv").write_text(text)
    with pytest.raises(BundleError, match=problem):
        read_clouds(tmp_path)


def test_clouds_arrays_are_checked():
    with pytest.raises(ObservationError, match="empty"):
        Clouds((np.zeros((3, 2)), np.zeros((0, 2))))
    with pytest.raises(ObservationError, match="NaN"):
        Clouds((np.zeros((3, 2)), np.array([[1.0, np.nan]])))
    with pytest.raises(ObservationError, match="at least one deformed frame"):
        Clouds((np.zeros((3, 2)),))
    with pytest.raises(ObservationError, match="mix"):
        Clouds((np.zeros((3, 2)), np.zeros((3, 3))))
