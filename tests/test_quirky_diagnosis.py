"""The diagnosis on bundles from an independent solver (``tests/_independent2d.py``: gmsh, scikit-fem
P2, plane-stress neo-Hookean): the noise-free square of issue 44 named a rectangle with its ratio
within 1 %, and a few of ``benchmarks/quirky.py``'s draws (the benchmark runs all twenty). Slow:
each is a data solve and a diagnosis (minutes)."""

import numpy as np
import pytest

from refine.diagnosis.config import DiagnoseConfig
from refine.diagnosis.pipeline import diagnose
from tests._independent2d import quirky_bundle, square_bundle


@pytest.mark.slow
def test_the_noise_free_square_is_named_a_rectangle_with_its_ratio():
    """20 x 20 mm, ratio 10, 140 x 80 mm sheet pulled 15 %, observed on a 5 mm grid, 4 frames,
    exact data: the rectangle is named, its ratio within 1 % and its half sides within 0.5 mm."""
    bundle, square = square_bundle(h=2.0)
    d = diagnose(bundle, DiagnoseConfig(try_laws=False, discretisation_error=False), log=lambda m: None)
    assert d.chosen.cause == "stiffer-region" and len(d.chosen.shapes) == 1
    s = d.chosen.shapes[0]
    assert s.kind == "rectangle", d.chosen.describe()
    assert abs(s.ratio / square.ratio - 1) < 0.01, d.chosen.describe()
    assert np.allclose(sorted(s.axes), [square.a, square.b], atol=0.5), d.chosen.describe()
    assert np.hypot(s.centre[0] - square.cx, s.centre[1] - square.cy) < 0.5


@pytest.mark.slow
@pytest.mark.parametrize("seed, quirk, kind", [(100, "thinned", "hole"), (101, "rim", "hole"), (102, "edge", "none")])
def test_quirky_draws_name_the_right_cause(seed, quirk, kind):
    """benchmarks/quirky.py's first three draws: a hole in a thinned lattice, a hole whose rim holds
    straddling subsets, a sound sheet whose free edges are noisy (no finding)."""
    bundle, effect = quirky_bundle(seed, quirk, kind, frames=1)
    d = diagnose(bundle, DiagnoseConfig(try_laws=False, discretisation_error=False), log=lambda m: None)
    assert d.chosen.cause == kind, d.chosen.describe()
    if kind == "hole":
        s = d.chosen.shapes[0]
        assert np.hypot(s.centre[0] - effect.cx, s.centre[1] - effect.cy) < 2.0
