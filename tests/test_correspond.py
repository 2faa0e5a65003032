"""Tracking without correspondences (refine.correspond): the outline split, the model's outline,
the differentiable fit and the paper's Hausdorff force method on unlabelled clouds of a sheet
drawn at random under seeds (an independent finer quadratic solve, noise), and bad input."""

from __future__ import annotations

import numpy as np
import pytest

from refine.bundle.experiment import Experiment, PolygonDomain, RectangleDomain
from refine.correspond import CloudModel, FitConfig, Fitter, Grips, HausdorffConfig, hausdorff_track, split_frames
from refine.correspond.geometry import inside, split_outline
from refine.exceptions import CorrespondenceError
from examples.synthetic.clouds import cloud_sequence, outline_samples, random_cloud_truth

DOMAIN = (0.0, 0.0, 100.0, 50.0)


def _experiment(domain=RectangleDomain(*DOMAIN)):
    return Experiment(name="t", kind="plane-stress", domain=domain, law="neo-hookean", E=83.76, nu=0.3, thickness=1.0)


@pytest.fixture(scope="module")
def model():
    return CloudModel(_experiment(), Grips(), h=10.0)


@pytest.fixture(scope="module")
def sequence():
    """One frame of a random grip motion, no inclusion, fine tri6 mesh, noise 0.03 mm."""
    truth = random_cloud_truth(np.random.default_rng(11), "none", DOMAIN)
    return (*cloud_sequence(truth, seed=11, domain=DOMAIN, fractions=(1.0,), h=4.0, noise=0.03), truth)


@pytest.mark.parametrize("seed", [0, 1])
def test_outline_split_from_the_data_alone(seed):
    rng = np.random.default_rng(seed)
    noise = rng.uniform(0.01, 0.1)
    outline = outline_samples(rng, DOMAIN, 300)
    surface = np.stack([rng.uniform(0, 100, 100), rng.uniform(0, 50, 100)], 1)
    cloud = np.concatenate([outline, surface]) + rng.normal(0, noise, (400, 2))
    on = split_outline(cloud, 4 * noise)
    assert on[:300].mean() > 0.85 and on[300:].mean() < 0.05


def test_model_outline_is_oriented_and_encloses_the_domain(model):
    X = model.mesh.nodes
    A, B = X[model.facets[:, 0]], X[model.facets[:, 1]]
    mid, d = 0.5 * (A + B), B - A
    outward = np.stack([d[:, 1], -d[:, 0]], 1)
    centre = np.array([50.0, 25.0])
    assert np.all(np.einsum("ij,ij->i", outward, mid - centre) > 0)  # a convex domain: normals point away
    pts = np.array([[50.0, 25.0], [1.0, 1.0], [-1.0, 25.0], [50.0, 51.0]])
    assert np.asarray(inside(pts, A, B)).tolist() == [True, True, False, False]


def test_fit_recovers_the_grip_and_the_dense_motion(model, sequence):
    bundle, hidden, truth = sequence
    cfg = FitConfig(noise=0.03)
    train, held = split_frames(bundle.clouds.points, cfg)
    fitter = Fitter(model, cfg)
    Q, _, res = fitter.fit(train.frames([1]), np.zeros((1, 1, 3)), maxiter=80)
    x = np.asarray(fitter._positions(Q, fitter.zp0, model.start()))[0]
    err = np.linalg.norm(x - hidden.positions(model.mesh.nodes)[1], axis=1)
    assert np.sqrt((err ** 2).mean()) < 0.01 * 100.0  # the target: 1 % of the object's size
    assert np.sqrt((err ** 2).mean()) < 0.2  # and here, without an effect, much better
    g = truth.grip  # the unknowns mean what they say: the grip's translation and turn (times its half-length)
    np.testing.assert_allclose(Q[0, 0], [g.tx, g.ty, 25.0 * g.angle], atol=0.1)


def test_hausdorff_force_method_logs_and_closes_in(model, sequence):
    bundle, hidden, _ = sequence
    clouds = bundle.clouds.points
    r = hausdorff_track(model, clouds, HausdorffConfig(tol=0.1, noise=0.03, max_iterations=60))
    assert r.positions.shape == (2, model.mesh.n_nodes, 2) and r.forces.shape == (1, model.mesh.n_nodes, 2)
    first = r.log[0]
    assert {"frame", "iteration", "node", "side", "distance", "force", "hausdorff_after", "accepted"} <= set(first)
    assert r.largest[0] < 0.5 * first["distance"]  # the largest distance shrank
    err = np.linalg.norm(r.positions[1] - hidden.positions(model.mesh.nodes)[1], axis=1)
    start = np.linalg.norm(model.mesh.nodes - hidden.positions(model.mesh.nodes)[1], axis=1)
    assert np.sqrt((err ** 2).mean()) < 0.5 * np.sqrt((start ** 2).mean())


def test_bad_clouds_give_clear_errors(model):
    rng = np.random.default_rng(3)
    ref = outline_samples(rng, DOMAIN, 300)
    with pytest.raises(CorrespondenceError, match="reference cloud"):
        model.check_reference(ref + [40.0, 0.0], noise=0.03, tol=1.0)  # a cloud far from the model
    assert model.check_reference(ref + rng.normal(0, 0.03, ref.shape), noise=0.03, tol=1.0) < 0.2
    with pytest.raises(CorrespondenceError, match="empty"):
        split_frames([ref, np.zeros((0, 2))], FitConfig())
    bad = ref.copy()
    bad[5, 1] = np.nan
    with pytest.raises(CorrespondenceError, match="NaN"):
        split_frames([ref, bad], FitConfig())
    with pytest.raises(CorrespondenceError, match="outline"):
        split_frames([ref, rng.uniform(0, 50, (30, 2))], FitConfig(noise=0.01))
    with pytest.raises(CorrespondenceError, match="rectangle"):
        CloudModel(_experiment(PolygonDomain(((0.0, 0.0), (10.0, 0.0), (0.0, 10.0)))), Grips())


def test_every_method_refuses_bad_sequences_before_any_solve(model):
    """The issue's bad input (an empty frame, NaN, a reference cloud far from the model, a later
    frame far from the model fitted to it), given to the follow and to the Hausdorff method: a
    CorrespondenceError that names the frame and says what to do, raised before a solve."""
    from refine.correspond import FollowConfig, follow_clouds
    from refine.correspond.follow import _check_frame

    rng = np.random.default_rng(13)
    ref = outline_samples(rng, DOMAIN, 300) + rng.normal(0, 0.03, (300, 2))
    nan = ref.copy()
    nan[rng.integers(300), rng.integers(2)] = np.nan
    shift = rng.uniform(30.0, 60.0) * np.array([np.cos(a := rng.uniform(0, 2 * np.pi)), np.sin(a)])
    cases = [([ref, ref, np.zeros((0, 2))], "frame 2 has an empty cloud"), ([ref, nan], "frame 1's cloud has NaN"),
             ([ref + shift, ref], "reference cloud"), ([ref], "at least one more frame")]
    hausdorff = HausdorffConfig(tol=0.1, noise=0.03)
    for clouds, message in cases:
        with pytest.raises(CorrespondenceError, match=message):
            follow_clouds(model.experiment, clouds, FollowConfig(fit=FitConfig(noise=0.03)), model=model)
        with pytest.raises(CorrespondenceError, match=message):
            hausdorff_track(model, clouds, hausdorff)
    train, _ = split_frames([ref, ref + shift], FitConfig(noise=0.03))  # frame 1 far from where the model went
    with pytest.raises(CorrespondenceError, match="frame 1's cloud lies .* add the frames between"):
        _check_frame(model, model.mesh.nodes, train.frames([1]), 1, 0.05 * model.size)
    _check_frame(model, model.mesh.nodes, train.frames([0]), 1, 0.05 * model.size)  # frame 0 on the model: fine


def test_misfit_gradient_passes_a_taylor_test(model, sequence):
    """The adjoint gradient of the clouds' misfit in the grips and a modulus field (one implicit
    solve) against the misfit itself: the Taylor remainder falls as the step squared."""
    import jax

    import jaxfem as jf
    from refine.model.parametrize import ModulusField

    bundle, _, truth = sequence
    cfg = FitConfig(noise=0.03)
    train, _ = split_frames(bundle.clouds.points, cfg)
    fitter = Fitter(model, cfg, ModulusField(model.mesh, model.experiment.E, weight=1.0, kind="tv", eps=0.05))
    data, start = train.frames([1]).arrays(), model.start()
    f = jax.jit(lambda p: fitter.value(p["Q"], p["z"], data, start, train.spacing, 0.1))
    rng = np.random.default_rng(5)
    g = truth.grip
    point = {"Q": np.array([[[0.9 * g.tx, 0.9 * g.ty, 20.0 * g.angle]]]), "z": rng.normal(0, 0.2, model.mesh.n_cells)}
    direction = {"Q": rng.normal(0, 1.0, (1, 1, 3)), "z": rng.normal(0, 1.0, model.mesh.n_cells)}
    result = jf.taylor_test(f, point, direction, h0=1e-3, steps=4)
    assert np.all(result.rates1 > 1.8), result
