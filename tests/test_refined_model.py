"""The refined model as input: ``diagnose`` writes ``OUT/refined/``, a bundle whose initial model
is the chosen one; ``simulate`` and ``diagnose`` read it back.

The fast tests take a fitted model of each kind (a region, a hole, another law) at unknowns drawn
at random under a seed, without fitting (the writer does not care how the model was chosen),
on data from a finer quadratic solve of a sheet hiding a random effect, with noise: the refined
bundle is read back, the model built from it has the region's cells at the fitted modulus, and
simulating it reproduces the chosen model's predictions to the solver's tolerance. The slow test
diagnoses such a bundle, simulates the refined bundle and diagnoses it again: nothing is left
beyond the noise.
"""

from __future__ import annotations

import csv

import numpy as np
import pytest

import jaxfem as jf
from refine.bundle import read_bundle
from refine.cli import diagnose, simulate
from refine.diagnosis import refined
from refine.diagnosis.fitted import Fitted, Unchanged, material_law
from refine.diagnosis.holes import HoleHypothesis
from refine.diagnosis.pipeline import Diagnosis
from refine.diagnosis.regions import regions_hypothesis
from refine.diagnosis.shapes import RegionShape
from refine.model import MeasuredModel, UniformParameter
from refine.model.known import region_cells
from refine.model.objective import Compiled
from refine.model.parametrize import Combined
from refine.demo_data import random_truth, synthetic_bundle


@pytest.fixture(scope="module")
def bundle():
    truth = random_truth(np.random.default_rng(5), "stiffer-region")
    return synthetic_bundle(truth, seed=5, spacing=10.0, fractions=(0.5, 1.0), h=3.0, name="sheet")


def _predicted_csv(path, ids) -> np.ndarray:
    column = {int(i): k for k, i in enumerate(ids)}
    rows = list(csv.DictReader(open(path)))
    frames = max(int(r["frame"]) for r in rows)
    out = np.full((frames, len(ids), 2), np.nan)
    for r in rows:
        out[int(r["frame"]) - 1, column[int(r["id"])]] = float(r["ux"]), float(r["uy"])
    return out


def _chosen(bundle, cause: str, rng) -> Fitted:
    """A model of ``cause`` at random unknowns (a shape moved and turned a little, a ratio, a
    law's parameters), as the diagnosis would hand it over."""
    base = MeasuredModel(bundle.experiment, bundle.observations)
    z0 = None
    if cause == "material-law":
        from dataclasses import replace

        model = MeasuredModel(replace(bundle.experiment, law="mooney-rivlin"), bundle.observations, mesh=base.mesh)
        hyp = material_law("mooney-rivlin")
        compiled = Compiled(model, Combined((UniformParameter("nu", 0.3, 0.0, 0.499),
                                             UniformParameter("c01_fraction", 0.25, 0.0, 0.95))))
    elif cause == "hole":  # in the middle of a cell of the 10 mm grid of tracked points, none inside
        centre = (25.0 + 10 * rng.integers(2, 8), 15.0 + 10 * rng.integers(1, 4))
        hyp = HoleHypothesis(base, jf.Ellipse(*centre, *rng.uniform(3, 5, 2), rng.uniform(0, np.pi)))
        compiled, z0 = hyp.build()
    else:
        centre = (rng.uniform(50, 90), rng.uniform(30, 50))
        shape = RegionShape(centre, tuple(rng.uniform(5, 9, 2)), rng.uniform(0, np.pi), cause, rng.uniform(2, 8))
        hyp = regions_hypothesis(base, [shape], [1], element="tri6")
        compiled, z0 = hyp.build()
    z = (0.0 if z0 is None else z0) + rng.uniform(-0.1, 0.1, compiled.param.size)
    predicted = np.asarray(compiled.predict(z))
    return Fitted(hyp, len(z), 0.0, 0.0, 0.0, predicted, compiled.model, compiled.param.apply(compiled.theta, z),
                  1.0, shapes=hyp.shapes_at(compiled, z), compiled=compiled, z=z)


@pytest.mark.parametrize("cause,seed", [("ellipse", 1), ("hole", 3),
                                        # each ~30 s of compilation more: run with -m slow
                                        pytest.param("rectangle", 2, marks=pytest.mark.slow),
                                        pytest.param("material-law", 4, marks=pytest.mark.slow)])
def test_the_refined_bundle_reproduces_the_chosen_model(bundle, cause, seed, tmp_path):
    chosen = _chosen(bundle, cause, np.random.default_rng(seed))
    d = Diagnosis(bundle, None, None, chosen, [], [], None, chosen.model)
    root = refined.write(d, tmp_path)
    again = read_bundle(root)
    ex = again.experiment
    assert ex == refined.refined_experiment(d) and ex.name == "sheet-refined" and ex.mesh == "mesh.vtu"
    assert np.array_equal(again.observations.displacements, bundle.observations.displacements, equal_nan=True)
    model = MeasuredModel(ex, again.observations, root=root)
    if cause == "material-law":
        assert (ex.law, ex.nu) == ("mooney-rivlin", pytest.approx(float(chosen.theta["nu"][0]), abs=0))
        assert ex.parameters == {"c01_fraction": pytest.approx(float(chosen.theta["c01_fraction"][0]), abs=0)}
    elif cause == "hole":
        (hole,) = [h for h in ex.domain.holes if hasattr(h, "kind")]
        s = chosen.shapes[0]
        assert (hole.kind, hole.centre, hole.axes, hole.angle) == ("ellipse", tuple(s.centre), tuple(s.axes), s.angle)
        assert not hole.contains(model.mesh.centroids()).any()
    else:
        (region,) = ex.regions
        s = chosen.shapes[0]
        assert (region.shape.kind, region.shape.centre, region.shape.axes) == (s.kind, tuple(s.centre), tuple(s.axes))
        assert region.relative_elasticity == s.ratio
        cells = region_cells(model.mesh, ex)[0]
        assert np.array_equal(cells, chosen.model.mesh.regions == 1)
        E = np.asarray(model.params()["E"])
        assert np.allclose(E[cells], s.ratio * ex.E, rtol=1e-12) and np.allclose(E[~cells], ex.E, rtol=1e-12)
        assert region.shape.contains(model.mesh.centroids()[cells]).all()
    simulate(root, tmp_path / "sim", quiet=True)
    predicted = _predicted_csv(tmp_path / "sim" / "displacements.csv", again.observations.ids)
    _assert_reproduces(predicted, chosen, model.mesh)


def _assert_reproduces(predicted, chosen: Fitted, mesh) -> None:
    """``predicted`` (by the refined bundle's model, on ``mesh``) is ``chosen``'s displacement
    field at the points to the solver's tolerance, and so are ``chosen``'s own predictions at
    every point, also those the fit's geometry morph carried into another cell
    (``jaxfem.Probe.moved`` finds them there, as the refined model locates them afresh)."""
    from jaxfem.probe import _inverse_map

    scale = np.abs(chosen.predicted).max()
    field = jf.locate(mesh, chosen.model.obs.reference)
    U = np.asarray(chosen.model.solve_frames(chosen.theta))
    assert np.abs(predicted - np.stack([np.asarray(field(u)) for u in U])).max() < 1e-6 * scale
    _, outside = _inverse_map(mesh, chosen.model.probe.cells, chosen.model.obs.reference)
    print(f"{(outside > 1e-9).sum()} of {outside.size} points left the cell they were located in")
    assert np.abs(predicted - chosen.predicted).max() < 1e-6 * scale


def test_nothing_found_leaves_the_experiment_as_it_was(bundle, tmp_path):
    base = MeasuredModel(bundle.experiment, bundle.observations)
    chosen = Fitted(Unchanged("neo-hookean"), 0, 0.0, 0.0, 0.0, None, base, base.params(), 1.0)
    root = refined.write(Diagnosis(bundle, None, None, chosen, [], [], None, base), tmp_path)
    assert read_bundle(root).experiment == bundle.experiment and not (root / "mesh.vtu").exists()


@pytest.mark.slow
def test_diagnosing_the_refined_bundle_finds_nothing_more(tmp_path):
    """A bundle hiding a random stiff region is diagnosed; its refined bundle, simulated, gives
    the chosen model's predictions, and diagnosed again, shows nothing beyond the noise."""
    truth = random_truth(np.random.default_rng(11), "stiffer-region")
    b = synthetic_bundle(truth, seed=11, spacing=5.0, fractions=(0.5, 1.0))
    d = diagnose(b, tmp_path / "first", quiet=True)
    assert [f.cause for f in d.findings] == ["stiffer-region"], d.chosen.describe()
    root = tmp_path / "first" / "refined"
    simulate(root, tmp_path / "sim", quiet=True)
    predicted = _predicted_csv(tmp_path / "sim" / "displacements.csv", b.observations.ids)
    _assert_reproduces(predicted, d.chosen, jf.read_mesh(root / "mesh.vtu"))
    again = diagnose(root, tmp_path / "second", quiet=True)
    assert again.findings == [], again.chosen.describe()
    assert again.null.p_value > 1e-3
