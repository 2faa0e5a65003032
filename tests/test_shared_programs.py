"""One compiled program per bucket: solvers and models of different meshes of about the same size
reuse the solve's programs (jaxfem.program, jaxfem.padding), with the same results as a solve at
the real sizes. Small sheets (about 120 cells), their loads drawn under a seed."""

import jax
import numpy as np
import pytest

import jaxfem as jf
from jaxfem import padding
from refine.bundle.experiment import Experiment, RectangleDomain
from refine.bundle.observations import Observations
from refine.diagnosis.regions import region_model
from refine.model.measured import MeasuredModel


class Compiles:
    """Counts XLA compilations while active."""

    def __init__(self):
        self.n, self.on = 0, False
        jax.monitoring.register_event_duration_secs_listener(self._listen)

    def _listen(self, event, duration, **kw):
        if self.on and event.endswith("backend_compile_duration"):
            self.n += 1

    def __enter__(self):
        self.n, self.on = 0, True
        return self

    def __exit__(self, *exc):
        self.on = False


COMPILES = Compiles()


def _sheet(nx, ny, rng, linear_solver="superlu"):
    mesh = jf.rectangle(0, 0, 100, 60, nx, ny)
    fixed = np.concatenate([jf.dofs(mesh, mesh.side("left")), jf.dofs(mesh, mesh.side("right"))])
    problem = jf.Problem(mesh, "neo-hookean", "plane-stress", fixed=fixed)
    stretch, shear = rng.uniform(5, 15), rng.uniform(-3, 3)
    pull = problem.prescribe(lambda X: np.where(X[:, :1] > 50, [stretch, shear], 0.0))
    E = rng.uniform(50, 100, mesh.n_cells)  # a random modulus per cell
    return jf.Solver(problem, linear_solver), problem.params(E=E, nu=0.3, thickness=1.0, u_D=pull)


def _two_sheets(rng):
    a, theta_a = _sheet(10, 6, rng)
    b, theta_b = _sheet(9, 7, rng)
    return (a, theta_a), (b, theta_b)


def test_two_meshes_of_one_bucket_share_the_solve():
    """The second mesh of a bucket compiles nothing (no recompilation for another mesh of about
    the same size, nor for other parameter values)."""
    (a, theta_a), (b, theta_b) = _two_sheets(np.random.default_rng(7))
    assert a.problem.mesh.n_cells != b.problem.mesh.n_cells and a.sizes != b.sizes
    assert (a.sizes.n_cells_p, a.sizes.n_nodes_p, a.sizes.nnz_p, a.sizes.n_fixed_p) == \
        (b.sizes.n_cells_p, b.sizes.n_nodes_p, b.sizes.nnz_p, b.sizes.n_fixed_p)
    assert a.program is b.program
    u_a = a.solve(theta_a).u
    cached = a.program.newton._cache_size()  # other tests in this process may have filled other buckets
    with COMPILES as c:
        u_b = b.solve(theta_b).u
        b.solve({**theta_b, "E": 2.0 * np.asarray(theta_b["E"])})
    assert c.n == 0, f"the second mesh of the bucket compiled {c.n} programs"
    assert a.program.newton._cache_size() == cached
    for solver, u in ((a, u_a), (b, u_b)):  # the prescribed motion is met, the body is not torn
        fixed = solver.problem.fixed
        assert np.all(np.isfinite(u)) and np.abs(np.asarray(u).reshape(-1)[fixed]).max() > 1.0


@pytest.mark.slow
def test_padded_solves_equal_the_real_sizes_and_their_tangents_the_jvp():
    """The padded solve is the solve at the real sizes (the dense solver on an unpadded system);
    the tangents along random directions are those of the differentiable map."""
    rng = np.random.default_rng(7)
    (a, theta_a), (b, theta_b) = _two_sheets(rng)
    for solver, theta in ((a, theta_a), (b, theta_b)):
        u = solver.solve(theta).u
        want = unpadded_solve(solver, theta)
        np.testing.assert_allclose(u, want, atol=1e-9 * np.abs(want).max())
    d = {k: np.zeros((2,) + np.shape(v)) for k, v in theta_b.items()}
    d["E"] = rng.normal(0, 5.0, d["E"].shape)
    d["X"][:, :, 1] = rng.normal(0, 0.1, d["X"].shape[:2]) * (b.problem.free_mask.reshape(-1, 2)[:, 1])
    _, du, _ = b.solve_with_tangents(theta_b, d)
    jvp = jax.jit(lambda th, dd: jax.jvp(b.displacement, (th,), (dd,))[1])
    for i in range(2):
        jv = jvp(theta_b, {k: v[i] for k, v in d.items()})
        np.testing.assert_allclose(du[i], jv, atol=1e-8 * np.abs(jv).max())
        assert np.abs(jv).max() > 1e-6


def unpadded_solve(solver, theta):
    """The displacements of ``solver``'s problem at ``theta`` solved densely at its real sizes (no
    padding): the reference a padded solve must equal."""
    return real_size_solver(solver.problem).solve(theta).u


def real_size_solver(problem):
    """A dense solver of ``problem`` at its real sizes (no padding cells, dofs, entries nor traction
    facets)."""
    ref = jf.Solver(problem, "dense")
    s = ref.sizes
    ref.sizes = padding.sizes(s.n_cells, s.n_nodes, s.dim, s.nnz, s.n_fixed, pad=False, n_facets=s.n_facets)
    arr = padding.padded_arrays(ref.sizes, problem.mesh.cells, ref.pattern, problem.fixed, problem.free_mask,
                                problem.traction_facets)
    ref.padded_arrays = {**ref.padded_arrays, **{k: jax.numpy.asarray(v) for k, v in arr.items()}}
    return ref


def test_bucket_sizes():
    assert [padding.bucket(n) for n in (1, 16, 17, 20, 21, 128, 129)] == [16, 16, 20, 20, 23, 128, 153]
    for n in np.random.default_rng(3).integers(17, 10**6, 50):
        b = padding.bucket(int(n))
        assert n <= b < 1.19 * n + 1


def _sheet_bundle(rng):
    """A 40 x 30 mm sheet tracked on a 5 mm grid (edge points drive it), stretched and sheared."""
    X, Y = np.meshgrid(np.arange(0.0, 40.1, 5.0), np.arange(0.0, 30.1, 5.0))
    pts = np.stack([X.ravel(), Y.ravel()], 1)
    edge = (pts[:, 0] == 0) | (pts[:, 0] == 40) | (pts[:, 1] == 0) | (pts[:, 1] == 30)
    a = rng.uniform(0.005, 0.02, 2)
    u = np.stack([a[0] * pts[:, 0], a[1] * pts[:, 1]], 1)
    disp = np.stack([0.5 * u, u]) + rng.normal(0, 0.002, (2, *pts.shape))
    ex = Experiment("pulled", "plane-stress", RectangleDomain(0.0, 0.0, 40.0, 30.0), "neo-hookean", 1.0, 0.3,
                    noise_std=0.002)
    return ex, Observations(np.arange(len(pts)), pts, np.where(edge, "boundary", "guide"), disp)


def _region_models(rng):
    ex, obs = _sheet_bundle(rng)
    base = MeasuredModel(ex, obs, h=4.0)
    c = rng.uniform([15, 12], [25, 18])
    shapes = ((0.0, 5.0), (1.3, 6.0))
    return [region_model(base, [jf.Ellipse(c[0] + dx, c[1], a, 4.0, 0.3)], 2.5) for dx, a in shapes]


Z = np.array([np.log(2.0), 0.1, -0.05, 0.05, 0.02, 0.0])  # log ratio, then the ellipse's changes


def test_two_region_hypotheses_of_one_bucket_compile_one_solve():
    """Two region models (meshes that follow different ellipses) of one bucket: the second one's
    prediction and Jacobian compile no solve of its own; the Jacobian is the prediction's
    derivative (central differences along a random direction)."""
    from refine.model.objective import Compiled

    rng = np.random.default_rng(11)
    (m1, p1), (m2, p2) = _region_models(rng)
    assert m1.mesh.n_cells != m2.mesh.n_cells, (m1.mesh.n_cells, m2.mesh.n_cells)
    assert m1.solver.program is m2.solver.program
    Compiled(m1, p1).evaluate(Z)
    prog = m1.solver.program
    cached = prog.newton._cache_size(), prog.tangents._cache_size()  # other tests may have filled other buckets
    second = Compiled(m2, p2)
    pred, J = second.evaluate(Z)
    assert (prog.newton._cache_size(), prog.tangents._cache_size()) == cached, "the second mesh recompiled"
    d, eps = rng.normal(size=Z.size), 1e-5
    fd = (second.predict(Z + eps * d) - second.predict(Z - eps * d)) / (2 * eps)
    np.testing.assert_allclose(J @ d, fd, atol=1e-5 * np.abs(fd).max())


@pytest.mark.slow
def test_shared_programs_equal_the_whole_chain_in_one_program():
    """Compiled's prediction and Jacobian, a field's misfit gradient and the drive Jacobian on the
    shared programs equal the whole chain differentiated by JAX in one program (as before)."""
    from refine.model.objective import Compiled, Objective
    from refine.model.parametrize import ModulusField

    rng = np.random.default_rng(11)
    _, (m2, p2) = _region_models(rng)
    pred, J = Compiled(m2, p2).evaluate(Z)

    def f(zz):
        y = m2.predict(p2.apply(m2.params(), zz))
        return y, y

    J_ref, pred_ref = jax.jit(jax.jacfwd(f, has_aux=True))(Z)
    np.testing.assert_allclose(pred, pred_ref, atol=1e-10 * np.abs(pred_ref).max())
    np.testing.assert_allclose(J, J_ref, atol=1e-7 * np.abs(J_ref).max())
    model = m2
    objective = Objective(model, ModulusField(model.mesh, model.experiment.E, weight=1e-3))
    z = rng.normal(0, 0.3, objective.param.size)
    value, grad = objective.value_and_grad(z)
    want_value, want_grad = jax.jit(jax.value_and_grad(objective.value))(z)
    assert float(value) == pytest.approx(float(want_value), rel=1e-9)
    np.testing.assert_allclose(grad, want_grad, atol=1e-7 * np.abs(want_grad).max())
    theta = model.params()
    got = model.boundary_jacobian(theta)
    want = jax.jit(jax.jacfwd(lambda b: model.predict(theta, boundary=b)))(model.measured_boundary())
    np.testing.assert_allclose(got, want, atol=1e-9 * np.abs(want).max())


@pytest.mark.slow
def test_field_gradient_and_drive_jacobian_on_the_shared_programs():
    """A modulus field's misfit gradient (the adjoint on the shared programs) and the prediction's
    derivatives in the driving boundary displacements, against central differences along random
    directions."""
    from refine.model.objective import Objective
    from refine.model.parametrize import ModulusField

    rng = np.random.default_rng(5)
    ex, obs = _sheet_bundle(rng)
    model = MeasuredModel(ex, obs, h=6.0)
    objective = Objective(model, ModulusField(model.mesh, ex.E, weight=1e-3))
    z = rng.normal(0, 0.3, objective.param.size)
    value, grad = objective.value_and_grad(z)
    d, eps = rng.normal(size=z.size), 1e-5
    fd = (objective.value_and_grad(z + eps * d)[0] - objective.value_and_grad(z - eps * d)[0]) / (2 * eps)
    assert float(np.dot(grad, d)) == pytest.approx(float(fd), rel=1e-5)
    theta, B = model.params(), model.measured_boundary()
    got = model.boundary_jacobian(theta)
    dB = rng.normal(size=B.shape)
    fd = (np.asarray(model.predict(theta, boundary=B + eps * dB)) - np.asarray(model.predict(theta, boundary=B - eps * dB))) / (2 * eps)
    np.testing.assert_allclose(np.einsum("fpdgm,gm->fpd", got, dB), fd, atol=1e-5 * np.abs(fd).max())


def test_host_solves_run_inside_their_programs_lock(monkeypatch):
    """With Newton's loop in one jitted program (``NONRIGID_NEWTON=jit``; on the host, the default,
    no program calls back into Python), every host solve (PARDISO here: a Python callback that needs the GIL) of what the
    diagnosis runs in its thread pool (a hypothesis's prediction and Jacobian, a model's
    prediction, the drive's Jacobian) runs inside its shared program's lock, where the caller
    waits for the result with the GIL released (jaxfem.program.Program.lock): no program of the
    model's own calls back into Python unguarded (a thread waiting for a busy executable while
    holding the GIL hung a diagnosis once)."""
    from jaxfem.linsolve import _base
    from refine.model.objective import Compiled

    rng = np.random.default_rng(13)
    monkeypatch.setenv("NONRIGID_NEWTON", "jit")
    (model, param), _ = _region_models(rng)
    if "host" not in model.solver.padded_arrays:
        pytest.skip("no host linear solver installed (PARDISO, SuperLU): no callback to guard")
    host = _base._HOSTS[int(model.solver.padded_arrays["host"])]
    lock, seen = model.solver.program.lock, []
    inner = host._cache

    def watched(vals, rhs):
        seen.append(lock.locked())
        return inner(vals, rhs)

    host._cache = watched
    try:
        z = Z + rng.normal(0, 0.01, Z.size)  # a point no earlier call cached
        Compiled(model, param).evaluate(z)
        model.predict(model.params())
        model.boundary_jacobian(model.params())
    finally:
        host._cache = inner
    assert seen and all(seen), f"{seen.count(False)} of {len(seen)} host solves ran outside the program's lock"


def _second_model_compiles_no_interpolation(element):
    from refine.model import interpolation

    rng = np.random.default_rng(23)
    ex, obs = _sheet_bundle(rng)
    h1 = rng.uniform(3.0, 3.4)
    m1 = MeasuredModel(ex, obs, h=h1, element=element)
    # the padded sizes a model gets depend on the programs this process already holds (a larger held
    # bucket is reused: jaxfem.program.sizes_for), so the second mesh is searched for, not assumed
    for h2 in h1 * np.r_[np.linspace(1.04, 1.5, 12), np.linspace(0.96, 0.7, 8)]:  # coarser, then finer
        m2 = MeasuredModel(ex, obs, h=h2, element=element)
        if m1.mesh.n_nodes != m2.mesh.n_nodes and m1.solver.sizes.n_nodes_p == m2.solver.sizes.n_nodes_p:
            break
    else:
        pytest.fail(f"no other mesh shares the first model's padded sizes {m1.solver.sizes}")

    def run(m, frames):
        U = rng.normal(size=(frames, m.mesh.n_nodes, 2))
        dU, dX = rng.normal(size=(3, frames, m.mesh.n_nodes, 2)), rng.normal(size=(3, m.mesh.n_nodes, 2))
        pred, d = m.at_points_and_derivatives(U, dU, np.asarray(m.mesh.nodes), 1e-3 * dX)
        assert d.shape == (3, frames, obs.n_points, 2)
        w, nodes = np.asarray(m.probe.weights), np.asarray(m.probe.nodes)  # the probe's own weights, in numpy
        np.testing.assert_allclose(pred, np.einsum("pk,fpkd->fpd", w, U[:, nodes]), rtol=0, atol=1e-12)

    run(m1, 2)
    cached = interpolation._jvp._cache_size()  # other tests may have filled other buckets
    run(m2, 3)
    assert interpolation._jvp._cache_size() == cached, "the second model compiled its own interpolation"


def test_a_second_model_of_the_bucket_compiles_no_interpolation():
    """The tracked points' interpolation and its derivatives (refine.model.interpolation): a
    second model of another mesh in the same bucket, on other frames, compiles no program of its
    own; unmorphed, the interpolation is the probe's own weights' (linear triangles here, the
    quadratic ones' program takes seconds to compile: under ``-m slow``)."""
    _second_model_compiles_no_interpolation("tri3")


@pytest.mark.slow
def test_a_second_quadratic_model_of_the_bucket_compiles_no_interpolation():
    _second_model_compiles_no_interpolation("tri6")


@pytest.mark.slow
def test_shared_interpolation_equals_the_models_own_program():
    """On a smoothly morphed mesh, linear and quadratic: the shared interpolation and its
    derivatives are bitwise those of the model's own program (``points_jvp``), and the concrete
    interpolation equal to the one run op by op to 1e-12 (another order of operations)."""
    from jaxfem.padding import BATCH, pad_batch

    rng = np.random.default_rng(29)
    ex, obs = _sheet_bundle(rng)
    for element in ("tri3", "tri6"):
        m = MeasuredModel(ex, obs, h=rng.uniform(3.0, 4.0), element=element)
        X0 = np.asarray(m.mesh.nodes)
        X = X0 + rng.uniform(0.2, 0.5) * np.sin(X0[:, ::-1] / rng.uniform(8, 12))
        for frames in (2, 3):
            U = rng.normal(size=(frames, m.mesh.n_nodes, 2))
            dU, dX = rng.normal(size=(11, frames, m.mesh.n_nodes, 2)), 1e-2 * rng.normal(size=(11, m.mesh.n_nodes, 2))
            pred, d = m.at_points_and_derivatives(U, dU, X, dX)
            dUp, dXp = pad_batch(dU, 11), pad_batch(dX, 11)
            own = [m.points_jvp(U, dUp[i: i + BATCH], X, dXp[i: i + BATCH]) for i in range(0, len(dUp), BATCH)]
            assert np.array_equal(pred, np.asarray(own[0][0]))
            assert np.array_equal(d, np.concatenate([np.asarray(b) for _, b in own])[:11])
            eager = jax.vmap(m.probe.moved(X, m.positions))(U)
            np.testing.assert_allclose(np.asarray(m.at_points(U, {"X": X})), eager, rtol=0, atol=1e-12)
