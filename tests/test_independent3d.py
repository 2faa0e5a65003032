"""The independent 3D solver (tests/_independent3d.py) against closed forms: a homogeneous bar
pulled uniaxially (free lateral faces) takes the neo-Hookean stretch solved from the 1D equation
and its nominal stress; its tangent is the residual's derivative; a gripped bar's response
converges under mesh refinement."""

import numpy as np
import pytest
from scipy.optimize import brentq

from tests._independent3d import (_forms, affine_drive, assemble_tangent, basis_of, component_dofs, gmsh_mesh, solve,
                                  tangent_tensor)

pytest.importorskip("gmsh")
pytest.importorskip("skfem")


def bar(L, W, h):
    return gmsh_mesh(lambda occ: occ.addBox(0, 0, 0, L, W, W), None, h)


def uniaxial_lateral(stretch, mu, lam):
    """Lateral stretch t of uniaxial stress: P_yy = mu t + (lam ln(stretch t^2) - mu) / t = 0."""
    return brentq(lambda t: mu * t * t + lam * np.log(stretch * t * t) - mu, 0.3, 1.5)


def test_uniaxial_bar_matches_the_closed_form():
    rng = np.random.default_rng(7)
    L, W = 20.0, float(rng.uniform(4.0, 6.0))
    E, nu, stretch = float(rng.uniform(20.0, 80.0)), float(rng.uniform(0.2, 0.45)), float(rng.uniform(1.05, 1.15))
    nodes, cells, _ = bar(L, W, 3.0)
    basis = basis_of(nodes, cells)
    at = lambda axis, v: (lambda x: np.isclose(x[axis], v))  # noqa: E731
    x0, xL = component_dofs(basis, at(0, 0.0), 0), component_dofs(basis, at(0, L), 0)
    y0, z0 = component_dofs(basis, at(1, 0.0), 1), component_dofs(basis, at(2, 0.0), 2)

    def drive(s):  # symmetry planes x = 0, y = 0, z = 0; the end x = L moved along x
        return np.r_[x0, xL, y0, z0], np.r_[0 * x0, np.full(len(xL), s * (stretch - 1) * L), 0 * y0, 0 * z0]

    sol = solve(basis, np.full(len(cells), E), nu, drive, [0.5, 1.0])
    mu, lam = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))
    for frame, s in enumerate([0.5, 1.0]):
        lx = 1 + s * (stretch - 1)
        t = uniaxial_lateral(lx, mu, lam)
        X = rng.uniform([0, 0, 0], [L, W, W], (20, 3))
        U = sol.at(X)[frame]
        expected = X * [lx - 1, t - 1, t - 1]
        assert np.abs(U - expected).max() < 1e-8 * L
        P = mu * lx + (lam * np.log(lx * t * t) - mu) / lx  # nominal stress along x
        assert sol.reaction(frame, xL) == pytest.approx(P * W * W, rel=1e-7)


def test_tangent_is_the_residuals_derivative():
    rng = np.random.default_rng(3)
    nodes, cells, _ = bar(10.0, 4.0, 2.5)
    basis = basis_of(nodes, cells)
    residual, block, state = _forms()
    mu = np.full(basis.X.shape[1:], 20.0) * rng.uniform(0.5, 2.0, (len(cells), 1))
    lam = 1.5 * mu
    u = 0.03 * rng.standard_normal(basis.N)
    R = lambda u: residual.assemble(basis, u=basis.interpolate(u), mu=mu, lam=lam)  # noqa: E731
    _, Fit, lnJ = state({"u": basis.interpolate(u)})
    K = assemble_tangent(basis, block, tangent_tensor(Fit, lnJ, mu, lam))
    v, eps = rng.standard_normal(basis.N), 1e-6
    fd = (R(u + eps * v) - R(u - eps * v)) / (2 * eps)
    assert np.abs(fd - K @ v).max() < 1e-6 * np.abs(fd).max()


def test_gripped_bar_converges_under_refinement():
    """Both ends gripped (every component held), one pulled 8 %: as h halves the end force converges
    (each change under half the last) and the mean lateral contraction over the middle of a side
    face stays within 0.2 % (it does not change monotonically on unstructured meshes)."""
    L, W = 12.0, 4.0
    g = np.stack(np.meshgrid(np.linspace(L / 3, 2 * L / 3, 6), np.linspace(0.5, W - 0.5, 6)), -1).reshape(-1, 2)
    probe = np.c_[g[:, 0], np.full(len(g), W), g[:, 1]]  # the middle third of the side face y = W
    values = []
    for h in (4.0, 2.0, 1.0):
        nodes, cells, _ = bar(L, W, h)
        basis = basis_of(nodes, cells)
        ends = lambda x: np.isclose(x[0], 0.0) | np.isclose(x[0], L)  # noqa: E731
        drive = affine_drive(basis, ends, lambda s, X: np.c_[s * 0.08 * X[:, :1], 0 * X[:, 1:]])
        sol = solve(basis, np.full(len(cells), 50.0), 0.3, drive, [1.0])
        xL = component_dofs(basis, lambda x: np.isclose(x[0], L), 0)
        values.append(np.r_[sol.at(probe)[0, :, 1].mean(), sol.reaction(0, xL)])
    d1, d2 = np.abs(values[1] - values[0]), np.abs(values[2] - values[1])
    assert d2[1] < 0.5 * d1[1], (values, d1, d2)  # the force: from above, each change under half the last
    assert np.all(np.abs(np.diff([v[0] for v in values])) < 2e-3 * abs(values[-1][0]))


@pytest.mark.slow
def test_a_body_bundle_reads_back_and_its_grips_move_as_prescribed(tmp_path):
    """The sound bracket's bundle (tests/_bodies3d.py) reads back with refine.bundle.io; its model
    mesh is the whole bracket; the clamped and the moved faces' points read the prescribed motion
    within 5 noise std; the other points are guide or validate."""
    import jaxfem as jf
    from refine.bundle.io import read_bundle
    from tests._bodies3d import BODIES, FRAMES, write_body_bundle

    root = write_body_bundle(tmp_path / "sound", "sound", seed=5)
    b = read_bundle(root)
    obs, body = b.observations, BODIES["bracket"]
    assert jf.read_mesh(root / "mesh.vtu").volumes().sum() == pytest.approx(60 * 20 * 15 + 40 * 20 * 15, rel=1e-9)
    X, roles, sigma = obs.reference, obs.roles, b.experiment.noise_std
    assert set(roles[roles != "boundary"]) == {"guide", "validate"}
    moved = np.isclose(X[:, 0], 60.0)
    clamped = np.isclose(X[:, 1], 60.0)
    assert np.all(roles[moved | clamped] == "boundary") and np.all(moved | clamped | (roles != "boundary"))
    for frame, s in enumerate(FRAMES):
        assert np.abs(obs.displacements[frame, moved] - body.motion(s, X[moved])).max() < 5 * sigma
        assert np.abs(obs.displacements[frame, clamped]).max() < 5 * sigma
