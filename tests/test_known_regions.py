"""Known regions and shaped holes in experiment.toml (``[[model.regions]]``, ``model.domain.holes``):
read, written, checked, and honoured by the model built from a bundle."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import tomli_w
import tomllib

from refine.bundle import Experiment, RectangleDomain, read_bundle, write_bundle
from refine.bundle.regions import KnownRegion
from refine.bundle.shapes import EllipseShape, PolygonShape, RectangleShape
from refine.exceptions import BundleError, ExperimentError
from refine.model import MeasuredModel, domain_mesh
from refine.model.known import region_cells


def _random_experiment(seed: int) -> Experiment:
    """A 100 x 60 sheet with an elliptic region, a rectangular region of another law, a polygon
    hole and an elliptic hole, placed at random (apart) under ``seed``."""
    rng = np.random.default_rng(seed)
    cols = rng.permutation(4)  # one quarter of the sheet each
    centre = [(14.0 + 24.0 * c + rng.uniform(-2, 2), 30.0 + rng.uniform(-8, 8)) for c in cols]
    ell = EllipseShape(centre[0], tuple(rng.uniform(4, 8, 2)), rng.uniform(0, np.pi))
    rect = RectangleShape(centre[1], tuple(rng.uniform(3, 6, 2)), rng.uniform(0, np.pi))
    t = np.linspace(0, 2 * np.pi, 7)[:-1]
    poly = tuple(zip(centre[2][0] + 5 * np.cos(t), centre[2][1] + 5 * np.sin(t)))
    hole = EllipseShape(centre[3], tuple(rng.uniform(3, 6, 2)), rng.uniform(0, np.pi))
    return Experiment(name="known", kind="plane-stress", law="neo-hookean", E=83.76, nu=0.3, thickness=1.0,
                      domain=RectangleDomain(0, 0, 100, 60, holes=(poly, hole)),
                      regions=(KnownRegion(ell, relative_elasticity=float(rng.uniform(2, 9)), name="stiff"),
                               KnownRegion(rect, modulus=float(rng.uniform(10, 40)), law="mooney-rivlin",
                                           parameters={"c01_fraction": 0.4}, name="scar")),
                      parameters={})


def _toml_round_trip(ex: Experiment) -> Experiment:
    return Experiment.from_toml(tomllib.loads(tomli_w.dumps(ex.to_toml())))


@pytest.mark.parametrize("seed", [1, 2])
def test_regions_and_shaped_holes_round_trip_through_toml(seed):
    ex = _random_experiment(seed)
    assert _toml_round_trip(ex) == ex
    with_mesh = dataclasses.replace(ex, mesh="mesh.vtu", law="mooney-rivlin", parameters={"c01_fraction": 0.1})
    assert _toml_round_trip(with_mesh) == with_mesh
    # an older experiment (no regions, polygon holes only) reads and writes as before
    plain = Experiment(name="p", kind="plane-stress", law="neo-hookean", E=1.0, nu=0.3,
                       domain=RectangleDomain(0, 0, 10, 10, holes=(((4, 4), (6, 4), (5, 6)),)))
    assert set(plain.to_toml()["model"]) == {"kind", "domain"}
    assert _toml_round_trip(plain) == plain


def _table(**model):
    return {"experiment": {"name": "e"}, "material": {"law": "neo-hookean", "E": 1.0, "nu": 0.3},
            "model": {"kind": "plane-stress", "domain": {"rectangle": [0, 0, 100, 60]}, **model}}


def _region(**kw):
    return {"ellipse": {"centre": [50, 30], "axes": [8, 5], "angle": 0.3}, "relative_elasticity": 3.0, **kw}


@pytest.mark.parametrize("model,message", [
    ({"regions": [_region(ellipse={"centre": [95, 30], "axes": [8, 5]})]}, "leaves the domain"),
    ({"regions": [_region(), _region(ellipse={"centre": [55, 32], "axes": [8, 5]})]}, "overlap"),
    ({"regions": [_region(relative_elasticity=0.0)]}, "relative_elasticity must be positive"),
    ({"regions": [_region(relative_elasticity=-2.0)]}, "relative_elasticity must be positive"),
    ({"regions": [_region(modulus=10.0)]}, "exactly one of relative_elasticity"),
    ({"regions": [_region(law="hookean")]}, "law 'hookean' is unknown; use one of"),
    ({"regions": [_region(c01_fraction=0.3)]}, "'c01_fraction' is no parameter of the neo-hookean law"),
    ({"regions": [{"relative_elasticity": 2.0}]}, "exactly one shape"),
    ({"regions": [_region(polygon=[[1, 1], [2, 1], [1, 2]])]}, "exactly one shape"),
    ({"regions": [_region(ellipse={"centre": [50, 30], "axes": [8, -5]})]}, "must be positive"),
    ({"regions": [_region(name="a"), _region(name="a", ellipse={"centre": [20, 20], "axes": [3, 3]})]},
     "names must differ"),
    ({"domain": {"rectangle": [0, 0, 100, 60], "holes": [{"ellipse": {"centre": [50, 30], "axes": [6, 4]}}]},
      "regions": [_region()]}, "overlap"),
    ({"domain": {"rectangle": [0, 0, 100, 60], "holes": [{"circle": [50, 30, 5]}]}}, "exactly one shape"),
    ({"domain": {"rectangle": [0, 0, 100, 60], "holes": [{"rectangle": {"centre": [99, 30], "half_sides": [4, 4]}}]}},
     "leaves the domain"),
])
def test_bad_regions_and_holes_are_named(model, message):
    with pytest.raises(ExperimentError, match=message):
        Experiment.from_toml(_table(**model))


def test_a_missing_model_mesh_file_is_named(tmp_path):
    from refine.bundle import Bundle, Observations

    pts = np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 60.0], [0.0, 60.0], [50.0, 30.0]])
    obs = Observations(np.arange(1, 6), pts, np.array(["boundary"] * 4 + ["guide"]), np.zeros((1, 5, 2)))
    ex = dataclasses.replace(_random_experiment(4), mesh="mesh.vtu")
    write_bundle(tmp_path, Bundle(ex, obs))
    with pytest.raises(BundleError, match="model.mesh names mesh file 'mesh.vtu'"):
        read_bundle(tmp_path)


def test_the_model_follows_known_regions_and_holes():
    """The model's mesh follows every region and hole: the cells of a region have its modulus
    (relative or absolute) and law, their area is the shape's (to the mesh's chords), no cell lies
    in a hole."""
    ex = _random_experiment(3)
    mesh = domain_mesh(ex, 1.5)
    cells = region_cells(mesh, ex)
    area = mesh.volumes()
    for region, inside in zip(ex.regions, cells):
        assert area[inside].sum() == pytest.approx(region.shape.area, rel=0.02)
        assert region.shape.contains(mesh.centroids()[inside]).all()
    for hole in ex.domain.holes:
        shape = hole if hasattr(hole, "kind") else PolygonShape(hole)
        assert not shape.contains(mesh.centroids()).any()
    from refine.demo_data import grid_points
    from refine.bundle import Observations

    pts = grid_points((0, 0, 100, 60), 10.0)
    keep = ~np.any([(h if hasattr(h, "kind") else PolygonShape(h)).contains(pts) for h in ex.domain.holes], 0)
    pts = pts[keep]
    edge = (pts[:, 0] % 100 == 0) | (pts[:, 1] % 60 == 0)
    obs = Observations(np.arange(len(pts)), pts, np.where(edge, "boundary", "guide"), np.zeros((1, len(pts), 2)))
    model = MeasuredModel(ex, obs, mesh=mesh)
    theta = model.params()
    E = np.asarray(theta["E"])
    stiff, scar = ex.regions
    assert np.allclose(E[cells[0]], stiff.relative_elasticity * ex.E) and np.allclose(E[cells[1]], scar.modulus)
    assert np.allclose(E[~cells.any(0)], ex.E)
    assert model.problem.material.name == "neo-hookean+mooney-rivlin"
    assert np.allclose(np.asarray(theta["share:mooney-rivlin"]), cells[1])
    assert np.allclose(np.asarray(theta["c01_fraction"])[cells[1]], 0.4)


def test_a_mixture_of_laws_is_each_law_where_its_share_is_one():
    import jax.numpy as jnp

    from jaxfem.materials import LAWS, mixture, share
    from jaxfem.exceptions import ProblemError

    rng = np.random.default_rng(0)
    F = jnp.asarray(np.eye(3) + 0.1 * rng.standard_normal((3, 3)))
    laws = (LAWS["neo-hookean"], LAWS["mooney-rivlin"], LAWS["saint-venant-kirchhoff"])
    mix = mixture(laws)
    p = {"E": 3.0, "nu": 0.3, "c01_fraction": 0.4}
    for law in laws:
        shares = {share(m.name): float(m is law) for m in laws}
        assert float(mix.energy(F, {**p, **shares})) == pytest.approx(float(law.energy(F, p)), rel=1e-12)
    assert [q.default for q in mix.extra if q.name.startswith("share:")] == [1.0, 0.0, 0.0]
    with pytest.raises(ProblemError, match="two or more distinct laws"):
        mixture((LAWS["neo-hookean"], LAWS["neo-hookean"]))
