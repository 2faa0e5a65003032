"""The 3D diagnosis's null test on the global model (refine.solid.null_level): the uniform modulus
fitted in closed form from the prediction alone, lost points left out; the null model named in
the settings. (The null test itself on a sound and a holed cup holder: benchmarks/diagnose3d.py
and the slow tests of test_solid_diagnosis.py: 3D solves take minutes here.)"""

import numpy as np
import pytest

from refine.solid.diagnose import SolidConfig
from refine.solid.null_level import scaled


def test_the_modulus_is_fitted_in_closed_form_and_lost_points_are_left_out():
    rng = np.random.default_rng(7)
    k = rng.uniform(0.9, 1.1)  # the data's displacements over the model's: modulus factor 1 / k
    pred = rng.normal(0.0, 0.2, (3, 40, 3))
    meas = k * pred + rng.normal(0.0, 1e-4, pred.shape)
    lost = rng.choice(40, 5, replace=False)
    meas[1, lost] = np.nan  # lost in frame 2: left out of the fit
    points = rng.uniform(size=40) < 0.7
    fitted, modulus = scaled(meas, pred, points, 0.005)
    assert modulus == pytest.approx(1.0 / k, rel=1e-3)
    assert np.allclose(fitted, pred / modulus)
    assert np.isfinite(fitted).all()


def test_the_null_model_is_one_the_diagnosis_has():
    assert SolidConfig().null_model == "global"
    assert SolidConfig(null_model="local").null_model == "local"
    with pytest.raises(ValueError, match="'global' or 'local'"):
        SolidConfig(null_model="wall")
