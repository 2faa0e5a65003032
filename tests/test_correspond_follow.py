"""Dynamic refinement while following unlabelled clouds (refine.correspond.follow_clouds and
``nonrigid follow``): a hidden stiff inclusion drawn at random under a seed makes the prediction
fail, the refinement it triggers finds the inclusion and predicts the last frames at least twice
better than the model never refined; a sequence without an effect is never refined. Slow (a
sequence, three follows): benchmarks/correspondence.py measures the same over more seeds."""

from __future__ import annotations

import json

import numpy as np
import pytest

from refine.bundle import write_bundle
from refine.bundle.io import Bundle
from refine.cli.main import main
from refine.correspond import CloudModel, FitConfig, FollowConfig, Grips, follow_clouds
from examples.synthetic.clouds import cloud_sequence, random_cloud_truth

DOMAIN = (0.0, 0.0, 100.0, 50.0)
NOISE = 0.015


def _sequence(cause, seed):
    truth = random_cloud_truth(np.random.default_rng(seed), cause, DOMAIN)
    bundle, hidden = cloud_sequence(truth, seed=seed, domain=DOMAIN, h=3.0, noise=NOISE)
    return truth, bundle, hidden


@pytest.fixture(scope="module")
def model():
    truth, bundle, _ = _sequence("none", 0)
    return CloudModel(bundle.experiment, Grips(), h=5.0)


@pytest.mark.slow
@pytest.mark.parametrize("seed", [21])
def test_refinement_finds_the_inclusion_and_predicts_better(model, seed):
    truth, bundle, hidden = _sequence("stiffer-region", seed)
    cfg = FollowConfig(fit=FitConfig(noise=NOISE, seed=seed))
    refined = follow_clouds(bundle.experiment, bundle.clouds.points, cfg, model=model)
    never = follow_clouds(bundle.experiment, bundle.clouds.points, FollowConfig(fit=cfg.fit, refine=False), model=model)
    assert any(r.refined for r in refined.records) and not any(r.refined for r in never.records)
    last = lambda res: np.mean([r.error_before for r in res.records[-2:]])  # noqa: E731
    assert last(never) >= 2.0 * last(refined)
    top = refined.findings[0]
    s = truth.inclusion.shape
    assert top["cause"] == "stiffer-region" and np.hypot(top["centroid"][0] - s.cx, top["centroid"][1] - s.cy) < 5.0
    # the refit keeps one region (a field's small compensating region at a free edge fails the BIC) and
    # places it closer than the field did
    assert len(refined.findings) == 1 and np.all(np.isfinite(top["centroid_se"]))
    field = refined.field_findings[0]["centroid"]
    assert np.hypot(top["centroid"][0] - s.cx, top["centroid"][1] - s.cy) <= np.hypot(field[0] - s.cx, field[1] - s.cy)
    err = np.linalg.norm(refined.positions - hidden.positions(model.mesh.nodes), axis=-1)
    assert np.sqrt((err ** 2).mean()) < 0.01 * 100.0


@pytest.mark.slow
def test_no_refinement_without_an_effect(model, tmp_path):
    _, bundle, hidden = _sequence("none", 22)
    write_bundle(tmp_path / "b", bundle)
    assert main(["follow", str(tmp_path / "b"), "--out", str(tmp_path / "out"), "--noise", str(NOISE)]) == 0
    summary = json.loads((tmp_path / "out" / "follow.json").read_text())
    assert summary["refinements"] == [] and summary["findings"] == []
    assert (tmp_path / "out" / "errors.png").stat().st_size > 0
    rows = np.loadtxt(tmp_path / "out" / "correspondences.csv", delimiter=",", skiprows=1)
    assert rows.shape[1] == 6 and set(rows[:, 0].astype(int)) == set(range(len(bundle.clouds.points)))


def test_follow_needs_clouds(tmp_path, capsys):
    from refine.bundle import Observations
    from refine.bundle.experiment import Experiment, RectangleDomain

    ex = Experiment(name="p", kind="plane-stress", domain=RectangleDomain(0.0, 0.0, 10.0, 5.0), law="neo-hookean",
                    E=1.0, nu=0.3, thickness=1.0)
    ref = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 5.0], [0.0, 5.0], [5.0, 2.5]])
    obs = Observations(np.arange(1, 6), ref, ["boundary"] * 4 + ["guide"], np.zeros((1, 5, 2)))
    write_bundle(tmp_path / "b", Bundle(ex, obs))
    assert main(["follow", str(tmp_path / "b"), "--out", str(tmp_path / "o")]) == 2
    assert "no clouds.csv" in capsys.readouterr().err


def test_diagnose_says_a_clouds_only_bundle_is_followed(tmp_path, capsys):
    from refine.bundle import Clouds
    from refine.bundle.experiment import Experiment, RectangleDomain

    ex = Experiment(name="c", kind="plane-stress", domain=RectangleDomain(0.0, 0.0, 10.0, 5.0), law="neo-hookean",
                    E=1.0, nu=0.3, thickness=1.0)
    write_bundle(tmp_path / "b", Bundle(ex, None, clouds=Clouds((np.ones((3, 2)), np.ones((4, 2))))))
    assert main(["diagnose", str(tmp_path / "b"), "--out", str(tmp_path / "o")]) == 2
    assert "nonrigid follow" in capsys.readouterr().err


def _with_points(bundle, hidden, rng, n=12):
    """The bundle with ``n`` tracked points too (random material points seen with noise)."""
    from refine.bundle import Observations

    X = np.stack([rng.uniform(5, 95, n), rng.uniform(5, 45, n)], 1)
    x = hidden.positions(X)
    U = x[1:] - X[None] + rng.normal(0, NOISE, x[1:].shape)
    return Bundle(bundle.experiment, Observations(np.arange(1, n + 1), X, ["guide"] * n, U), clouds=bundle.clouds)


def test_clouds_and_points_must_cover_the_same_frames(tmp_path):
    from refine.bundle import Clouds, read_bundle
    from refine.bundle.experiment import Experiment, RectangleDomain
    from refine.bundle import Observations
    from refine.exceptions import BundleError, ObservationError

    ex = Experiment(name="c", kind="plane-stress", domain=RectangleDomain(0.0, 0.0, 10.0, 5.0), law="neo-hookean",
                    E=1.0, nu=0.3, thickness=1.0)
    ref = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 5.0]])
    obs = Observations(np.arange(1, 4), ref, ["boundary"] * 3, np.zeros((2, 3, 2)))
    clouds = Clouds((np.ones((3, 2)), np.ones((4, 2))))  # one deformed frame, the points have two
    with pytest.raises(ObservationError, match="same frames"):
        write_bundle(tmp_path / "w", Bundle(ex, obs, clouds=clouds))
    write_bundle(tmp_path / "b", Bundle(ex, obs))
    (tmp_path / "b" / "clouds.csv").write_text("frame,x,y\n0,1,1\n1,1,2\n", encoding="utf-8")
    with pytest.raises(BundleError, match="clouds.csv.*same frames"):
        read_bundle(tmp_path / "b")


@pytest.mark.slow
def test_follow_fits_tracked_points_beside_the_clouds(model, tmp_path, capsys):
    _, bundle, hidden = _sequence("none", 23)
    both = _with_points(bundle, hidden, np.random.default_rng(23))
    write_bundle(tmp_path / "b", both)
    assert main(["follow", str(tmp_path / "b"), "--out", str(tmp_path / "out"), "--noise", str(NOISE),
                 "--no-refine"]) == 0
    assert "12 tracked points" in capsys.readouterr().out
    rows = np.loadtxt(tmp_path / "out" / "correspondences.csv", delimiter=",", skiprows=1)
    n = model.mesh.n_nodes
    pos = rows[:, 4:6].reshape(-1, n, 2)
    err = np.linalg.norm(pos - hidden.positions(rows[:n, 2:4]), axis=-1)
    assert np.sqrt((err ** 2).mean()) < 0.1  # as good as clouds alone (0.01 mm) to within the noise's scale
