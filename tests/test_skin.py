"""Skin with a burn scar (examples.skin.synthetic; issue 25 item 1): scars drawn at random under a
seed on skin of the paper's properties. That plane-stress skin does not lock at nu 0.49, and the
diagnosis naming, rating and placing the scar, are measured over seeds by benchmarks/scar.py."""

from __future__ import annotations


import numpy as np

import jaxfem as jf
from examples.skin.synthetic import SKIN, random_scar


def test_scars_are_drawn_at_random_inside_the_field_on_skin_of_the_papers_properties():
    x0, y0, x1, y1 = SKIN.roi
    margin = (y1 - y0) / 6
    scars = [random_scar(np.random.default_rng(seed)) for seed in range(60)]
    kinds = {type(t.inclusions[0].shape) for t in scars}
    assert kinds == {jf.Ellipse, jf.Rect}
    for t in scars:
        assert t.nu == 0.49 and 10 <= t.E <= 100 and 1.0 <= t.thickness <= 2.0
        inc = t.inclusions[0]
        assert SKIN.ratio[0] <= inc.ratio <= SKIN.ratio[1]
        cx, cy, a, b, _ = inc.shape.params
        assert x0 + margin <= cx - max(a, b) and cx + max(a, b) <= x1 - margin
        assert y0 + margin <= cy - max(a, b) and cy + max(a, b) <= y1 - margin
    centres = np.array([t.inclusions[0].shape.params[:2] for t in scars])
    assert np.ptp(centres[:, 0]) > 0.3 * (x1 - x0) and np.ptp(centres[:, 1]) > 0.1 * (y1 - y0)
    assert np.ptp([t.inclusions[0].ratio for t in scars]) > 0.5 * (SKIN.ratio[1] - SKIN.ratio[0])
