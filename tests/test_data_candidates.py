"""Candidates from what the data show, on synthetic bundles (a finer quadratic mesh of a larger
sheet, solved independently, with noise; effects drawn at random under a seed): the measured
strain map points at a hidden stiff region, and a hole without points is named a hole by a
diagnosis whose search uses fewer frames than the bundle has (the chosen model refitted on all)."""

import numpy as np
import pytest

from refine.diagnosis import DiagnoseConfig, diagnose
from refine.diagnosis.candidates import strain_regions
from refine.model.measured import MeasuredModel
from refine.demo_data import random_truth, synthetic_bundle

DIAGONAL = float(np.hypot(100.0, 60.0))


def test_the_measured_strain_map_points_at_a_stiff_region():
    truth = random_truth(np.random.default_rng(41), "stiffer-region")
    bundle = synthetic_bundle(truth, seed=41, spacing=5.0, noise=0.02, fractions=(1.0,))
    obs = bundle.observations
    model = MeasuredModel(bundle.experiment, obs, h=5.0)  # coarse: the initial model's strain only
    predicted = np.asarray(model.predict(model.params()))
    found = strain_regions(obs.reference, obs.displacements[0], predicted[0], 0.02, min_area=50.0, max_regions=2)
    stiff = [c for c in found if c.sign > 0]
    assert stiff and stiff[0].source == "strain"
    shape = truth.inclusions[0].shape
    assert np.hypot(*(stiff[0].centroid - [shape.cx, shape.cy])) < 0.05 * DIAGONAL, (stiff[0].centroid, shape)


@pytest.mark.slow  # a whole diagnosis and its refit on 3 frames: ~95 CPU s (1,726 s wall at load 35)
def test_a_hole_without_points_is_named_from_a_search_on_one_frame():
    truth = random_truth(np.random.default_rng(43), "hole")
    bundle = synthetic_bundle(truth, seed=43, spacing=5.0, noise=0.02, fractions=(0.3, 0.6, 1.0))
    d = diagnose(bundle, DiagnoseConfig(search_frames=1), log=lambda m: None)
    assert d.model.obs.n_frames == 1  # the search's model
    assert d.chosen.predicted.shape[0] == 3  # the chosen model, refitted on every frame
    assert [f.cause for f in d.findings] == ["hole"], d.chosen.describe()
    hole, found = truth.holes[0], d.findings[0].region
    assert np.hypot(*(np.asarray(found.centroid) - [hole.cx, hole.cy])) < 0.03 * DIAGONAL
    assert abs(found.area / (np.pi * hole.rx * hole.ry) - 1) < 0.10
    assert d.errors["gain"] >= 2.0
