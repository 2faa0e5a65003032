"""The tracked points' interpolation on programs shared by the models of a diagnosis
(refine.model.interpolation): the same values and derivatives as the model's own interpolation
(MeasuredModel.at_points, differentiated by JAX), and a second model of the bucket compiles
nothing. Small sheets (about 100-200 cells), their motion and regions drawn under a seed."""

import jax
import numpy as np
import pytest

import jaxfem as jf
from refine.bundle.experiment import Experiment, RectangleDomain
from refine.bundle.observations import Observations
from refine.diagnosis.regions import region_model
from refine.model import interpolation
from refine.model.measured import MeasuredModel


def _bundle(rng):
    """A 40 x 30 mm sheet tracked on a jittered 5 mm grid (edge points drive it), stretched and sheared."""
    X, Y = np.meshgrid(np.arange(0.0, 40.1, 5.0), np.arange(0.0, 30.1, 5.0))
    pts = np.stack([X.ravel(), Y.ravel()], 1)
    edge = (pts[:, 0] == 0) | (pts[:, 0] == 40) | (pts[:, 1] == 0) | (pts[:, 1] == 30)
    pts[~edge] += rng.uniform(-1.5, 1.5, (int((~edge).sum()), 2))
    a = rng.uniform(0.005, 0.02, 2)
    u = np.stack([a[0] * pts[:, 0] + 0.3 * a[1] * pts[:, 1], a[1] * pts[:, 1]], 1)
    disp = np.stack([0.5 * u, u, 1.5 * u]) + rng.normal(0, 0.002, (3, *pts.shape))
    ex = Experiment("pulled", "plane-stress", RectangleDomain(0.0, 0.0, 40.0, 30.0), "neo-hookean", 1.0, 0.3,
                    noise_std=0.002)
    return ex, Observations(np.arange(len(pts)), pts, np.where(edge, "boundary", "guide"), disp)


def _models(rng):
    """Two region models (tri3) of meshes that follow different ellipses."""
    ex, obs = _bundle(rng)
    base = MeasuredModel(ex, obs, h=4.0)
    c = rng.uniform([15, 12], [25, 18])
    a = rng.uniform(4.0, 7.0, 2)
    return [region_model(base, [jf.Ellipse(c[0] + dx, c[1], ai, 4.0, 0.3)], 2.5)[0] for dx, ai in zip((0.0, 1.3), a)]


def _own(model, U, dU, X, dX, C):
    """The model's own interpolation differentiated by JAX (what the shared programs replace)."""
    at = lambda UU, XX: model.at_points(UU, {"X": XX})  # noqa: E731
    pred = at(U, X)
    der = jax.vmap(lambda a, b: jax.jvp(at, (U, X), (a, b))[1])(dU, dX)
    pull = jax.vjp(lambda UU: at(UU, X), U)[1]
    return np.asarray(pred), np.asarray(der), np.asarray(jax.vmap(lambda c: pull(c)[0])(C))


@pytest.mark.parametrize("element", ["tri3", "tri6"])
def test_shared_interpolation_equals_the_models_own(element):
    """Values, derivatives along random directions of the displacements and of the (morphed)
    reference nodes, and the pull-back of random cotangents, on a model whose nodes moved:
    equal to the model's own to rounding."""
    rng = np.random.default_rng(23 if element == "tri3" else 29)
    model = MeasuredModel(*_bundle(rng), h=rng.uniform(3.5, 5.0), element=element)
    assert model.mesh.element == element
    n_f, n = model.obs.n_frames, model.mesh.n_nodes
    k, c = 11, 3  # more directions than one batch
    X = model.mesh.nodes + rng.normal(0, 0.05, (n, 2))  # a morph of under a tenth of a cell
    U = rng.normal(0, 0.5, (n_f, n, 2))
    dU, dX = rng.normal(size=(k, n_f, n, 2)), rng.normal(size=(k, n, 2))
    C = rng.normal(size=(c, n_f, model.obs.n_points, 2))
    want_pred, want_der, want_pull = _own(model, U, dU, X, dX, C)
    pred, der = model.at_points_and_derivatives(U, dU, X, dX)
    scale = np.abs(want_der).max()
    np.testing.assert_allclose(pred, want_pred, rtol=0, atol=1e-13 * np.abs(want_pred).max())
    np.testing.assert_allclose(der, want_der, rtol=0, atol=1e-13 * scale)
    np.testing.assert_allclose(model._points_vjp(U, X, C), want_pull, rtol=0, atol=1e-13 * np.abs(want_pull).max())


def test_a_second_model_of_the_bucket_compiles_no_interpolation():
    """Two region models (meshes that follow different ellipses, so other node and cell counts)
    of one bucket: the second one's interpolation and pull-back, on every frame, compile nothing."""
    rng = np.random.default_rng(35)
    m1, m2 = _models(rng)
    assert m1.mesh.n_nodes != m2.mesh.n_nodes
    (a1, n1, _), (a2, n2, _) = m1._shared_interpolation, m2._shared_interpolation
    assert n1 == n2 and {k: v.shape for k, v in a1.items()} == {k: v.shape for k, v in a2.items()}  # one bucket

    def run(m):
        n = m.mesh.n_nodes
        U, dU, dX = rng.normal(size=(3, n, 2)), rng.normal(size=(5, 3, n, 2)), rng.normal(size=(5, n, 2))
        m.at_points_and_derivatives(U, dU, m.mesh.nodes, dX)
        m._points_vjp(U[:1], m.mesh.nodes, rng.normal(size=(6, 1, m.obs.n_points, 2)))

    run(m1)
    cached = interpolation.weights_jvp._cache_size()
    run(m2)
    assert interpolation.weights_jvp._cache_size() == cached


def test_two_threads_needing_one_new_interpolation_compile_it_once():
    """Two hypotheses fitted side by side that need the same new interpolation program at once
    (here one model's, in two threads): one compilation."""
    from concurrent.futures import ThreadPoolExecutor

    from jaxfem import program

    rng = np.random.default_rng(37)
    model = MeasuredModel(*_bundle(rng), h=4.0, element="tri6")
    seen = []
    jax.monitoring.register_event_duration_secs_listener(
        lambda event, duration, **kw: seen.append(kw.get("fun_name"))
        if event.endswith("backend_compile_duration") else None)

    def run(m):
        n = m.mesh.n_nodes
        U, dU, dX = np.ones((1, n, 2)), np.ones((3, 1, n, 2)), np.zeros((3, n, 2))
        return m.at_points_and_derivatives(U, dU, m.mesh.nodes, dX)

    # forget what earlier tests compiled (their buckets may be these)
    interpolation.weights_jvp.clear_cache()
    program._READY.difference_update({k for k in program._READY if k[0] is interpolation.weights_jvp})
    with ThreadPoolExecutor(2) as pool:
        list(pool.map(run, (model, model)))
    assert interpolation.weights_jvp._cache_size() == 1
    assert sum("weights_jvp" in str(name) for name in seen) == 1, seen
