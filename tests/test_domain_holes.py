"""Known holes in a bundle's domain (``model.domain.holes``): read, written, meshed and modelled."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import jaxfem as jf
from refine.bundle import Experiment, PolygonDomain, RectangleDomain, read_bundle, write_bundle
from refine.exceptions import ExperimentError
from refine.model import MeasuredModel, domain_mesh


def _circle(cx, cy, r, n=24):
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return tuple(zip((cx + r * np.cos(t)).tolist(), (cy + r * np.sin(t)).tolist()))


def test_domains_with_holes_round_trip_and_older_domains_read_as_before():
    hole = _circle(60.0, 40.0, 8.0)
    base = dict(name="h", kind="plane-stress", law="neo-hookean", E=1.0, nu=0.3, thickness=1.0)
    for dom in (RectangleDomain(20, 10, 120, 70, holes=(hole,)),
                PolygonDomain(((20, 10), (120, 10), (120, 70), (20, 70)), holes=(hole, _circle(100, 30, 4))),
                RectangleDomain(20, 10, 120, 70)):
        ex = Experiment(domain=dom, **base)
        assert Experiment.from_toml(ex.to_toml()) == ex
    assert "holes" not in RectangleDomain(20, 10, 120, 70).to_toml()  # an older bundle's domain is unchanged
    with pytest.raises(ExperimentError, match=r"holes\[0\] needs at least 3"):
        RectangleDomain(0, 0, 1, 1, holes=(((0.2, 0.2), (0.4, 0.4)),))
    with pytest.raises(ExperimentError, match="a mesh has its holes"):
        Experiment.from_toml({"experiment": {"name": "m"}, "model": {"kind": "solid", "domain": {
            "mesh": "m.msh", "holes": [[[0, 0], [1, 0], [0, 1]]]}}, "material": {"law": "neo-hookean", "E": 1, "nu": 0.3}})


def test_the_model_mesh_leaves_a_known_hole_empty():
    rng = np.random.default_rng(4)
    cx, cy, r = rng.uniform(45, 95), rng.uniform(30, 50), rng.uniform(5, 9)
    ex = Experiment(name="h", kind="plane-stress", law="neo-hookean", E=1.0, nu=0.3, thickness=1.0,
                    domain=RectangleDomain(20, 10, 120, 70, holes=(_circle(cx, cy, r, 32),)))
    mesh = domain_mesh(ex, 2.5)
    centres = mesh.nodes[mesh.cells].mean(axis=1)
    assert not (np.hypot(centres[:, 0] - cx, centres[:, 1] - cy) < 0.95 * r).any()
    area = (100 * 60) - 32 / 2 * r**2 * np.sin(2 * np.pi / 32)
    a, b = (mesh.nodes[mesh.cells[:, k]] - mesh.nodes[mesh.cells[:, 0]] for k in (1, 2))
    cell_area = 0.5 * np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
    assert cell_area.sum() == pytest.approx(area, rel=1e-9)


def test_a_known_hole_in_the_model_predicts_a_holed_sheet_better(tmp_path):
    """Data from a finer quadratic solve of a sheet with a random elliptic hole, plus noise; the
    uniform model without the hole against the same model told of the hole (a polygon through the
    ellipse) in the bundle: the held-out error must drop severalfold."""
    from refine.measures import mean_position_error
    from refine.demo_data import random_truth, synthetic_bundle

    rng = np.random.default_rng(7)
    truth = random_truth(rng, "hole")
    bundle = synthetic_bundle(truth, seed=7, spacing=10.0, fractions=(1.0,), h=2.5, name="holed")
    hole = truth.holes[0]
    t = np.linspace(0, 2 * np.pi, 48, endpoint=False)
    c, s = np.cos(hole.angle), np.sin(hole.angle)
    ring = np.c_[hole.cx + hole.rx * np.cos(t) * c - hole.ry * np.sin(t) * s,
                 hole.cy + hole.rx * np.cos(t) * s + hole.ry * np.sin(t) * c]
    obs = bundle.observations
    keep = ~jf.Polygon(ring).contains(obs.reference)
    assert keep.all()  # the synthetic grid has no point in the hole
    told = dataclasses.replace(bundle.experiment, domain=dataclasses.replace(
        bundle.experiment.domain, holes=(tuple(map(tuple, ring)),)))
    write_bundle(tmp_path / "b", dataclasses.replace(bundle, experiment=told))
    back = read_bundle(tmp_path / "b")
    assert back.experiment.domain.holes == told.domain.holes
    errors = []
    for ex in (bundle.experiment, back.experiment):
        model = MeasuredModel(ex, obs, h=2.5)
        pred = np.asarray(model.predict(model.params()))
        v = obs.mask("validate")
        errors.append(mean_position_error(pred[:, v], obs.displacements[:, v]).value)
    assert errors[1] < errors[0] / 3
