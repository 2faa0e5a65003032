"""3D bundles (model kind "solid", a mesh file as the domain): written, read back and simulated.

The data are the closed-form homogeneous uniaxial stretch of a neo-Hookean block (lateral stretch
from P22 = 0, tests/_verify_util.uniaxial_neo_hookean), independent of any mesh, plus noise under
a seed; the model is a tet10 mesh of the block driven by the points on its two end faces.
"""

import numpy as np
import pytest

import jaxfem as jf
from examples.cup_holder import cup_holder
from refine.bundle.experiment import Experiment, MeshDomain
from refine.bundle.io import Bundle, read_bundle, write_bundle
from refine.bundle.observations import Observations
from refine.exceptions import ObservationError
from refine.cli.simulate import simulate
from tests._verify_util import lame, uniaxial_neo_hookean

E, NU = 10.0, 0.45
L, W = 4.0, 2.0  # block [0, L] x [0, W] x [0, W], mm


def block_points():
    """Ends x = 0 and x = L (3 x 3 grids each, boundary); top face (guide); front face (validate)."""
    g = np.array([0.0, 1.0, 2.0])
    ends = [np.array([x, y, z]) for x in (0.0, L) for y in g for z in g]
    top = [np.array([x, y, W]) for x in (1.0, 2.0, 3.0) for y in (0.5, 1.5)]
    front = [np.array([x, 0.0, 1.0]) for x in (1.0, 2.0, 3.0)]
    roles = ["boundary"] * len(ends) + ["guide"] * len(top) + ["validate"] * len(front)
    return np.array(ends + top + front), roles


def make_bundle(root, stretches=(1.03, 1.06), noise=1e-4, seed=0):
    root.mkdir()
    mesh = jf.box(0.0, 0.0, 0.0, L, W, W, 4, 2, 2, "tet10")
    jf.write_vtu(root / "mesh.vtu", mesh)
    X, roles = block_points()
    rng = np.random.default_rng(seed)
    U = []
    for s in stretches:
        lat, _ = uniaxial_neo_hookean(s, *lame(E, NU))
        U.append(X * (np.array([s, lat, lat]) - 1.0) + rng.normal(0.0, noise, X.shape))
    obs = Observations(np.arange(1, len(X) + 1), X, roles, np.array(U))
    exp = Experiment(name="block3d", kind="solid", domain=MeshDomain("mesh.vtu"), law="neo-hookean", E=E, nu=NU,
                     units={"length": "mm", "stress": "MPa", "force": "N"})
    write_bundle(root, Bundle(exp, obs))
    return exp, obs


def test_3d_bundle_round_trip_and_simulate(tmp_path):
    exp, obs = make_bundle(tmp_path / "b")
    back = read_bundle(tmp_path / "b")
    assert back.experiment == exp and back.observations.dim == 3
    np.testing.assert_allclose(back.observations.displacements, obs.displacements, rtol=1e-12, atol=1e-15)
    summary = simulate(back, tmp_path / "out", quiet=True)
    assert summary["frames"] == 2 and summary["cells"] == 96
    scale = np.linalg.norm(obs.displacements[:, obs.mask("guide")], axis=2).mean()
    # homogeneous data: the model reproduces it to the noise (1e-4 mm per component); the surface
    # drive is exact for a field linear along each face
    # (measured: 1.7e-4 and 1.8e-4 mm against a mean displacement of 0.10 mm, the noise's own size)
    assert summary["guide_error"] < 0.005 * scale and summary["validate_error"] < 0.005 * scale, (summary, scale)
    pred = read_bundle_displacements(tmp_path / "out" / "displacements.csv")
    assert pred.shape == (2, obs.n_points, 3)
    assert (tmp_path / "out" / "model_frame02.vtu").is_file()
    assert jf.read_mesh(tmp_path / "out" / "model_frame02.vtu").element == "tet10"


def read_bundle_displacements(path):
    rows = np.genfromtxt(path, delimiter=",", names=True)
    frames = int(rows["frame"].max())
    return np.stack([np.c_[r["ux"], r["uy"], r["uz"]] for r in (rows[rows["frame"] == f] for f in range(1, frames + 1))])


def test_3d_points_off_the_surface_are_named(tmp_path):
    from refine.model.measured import MeasuredModel

    exp, obs = make_bundle(tmp_path / "b")
    X = obs.reference.copy()
    X[0] = [-3.0, 1.0, 1.0]  # a boundary point 3 mm off the block
    bad = Observations(obs.ids, X, obs.roles, obs.displacements)
    with pytest.raises(ObservationError, match="1 boundary points are not on the mesh's surface.*point 1, is 3 away"):
        MeasuredModel(exp, bad, root=tmp_path / "b")


def test_3d_points_within_the_noise_of_the_surface_are_placed_on_it(tmp_path):
    """Measured surface points lie off the model's surface by their noise: within the tolerance
    (3 noise_std or a quarter of the spacing) they are projected onto it, drive and are compared
    there; the offsets are kept in the placement."""
    from refine.model.measured import MeasuredModel

    exp, obs = make_bundle(tmp_path / "b")
    rng = np.random.default_rng(5)
    X = obs.reference + rng.normal(0.0, 0.03, obs.reference.shape)  # every point jittered off the surface
    model = MeasuredModel(exp, Observations(obs.ids, X, obs.roles, obs.displacements), root=tmp_path / "b")
    moved = np.linalg.norm(model.positions - X, axis=1)
    assert 0 < moved.max() <= model.placement.tolerance
    on_faces = np.isclose(model.positions, 0.0, atol=1e-9) | np.isclose(model.positions, [L, W, W], atol=1e-9)
    assert on_faces[obs.roles == "boundary"].any(axis=1).all()
    assert np.isfinite(np.asarray(model.predict(model.params()))).all()


def test_surface_interpolation_is_exact_for_a_linear_field_and_stays_on_the_patch():
    from jaxfem.surface import surface_interpolation

    mesh = jf.box(0.0, 0.0, 0.0, L, W, W, 4, 2, 2, "tet10")
    rng = np.random.default_rng(7)
    pts = np.c_[rng.uniform(0.2, L - 0.2, 40), rng.uniform(0.2, W - 0.2, 40), np.full(40, W)]  # top face
    nodes, Wm = surface_interpolation(mesh, pts, radius=0.6)
    X = mesh.nodes[nodes]
    assert np.allclose(X[:, 2], W) and len(nodes) > 20  # only the top face is driven
    G = rng.normal(size=(3, 3))
    np.testing.assert_allclose(Wm @ (pts @ G.T), X @ G.T, atol=1e-10)
    with pytest.raises(jf.MeshError, match="at least three"):
        surface_interpolation(mesh, pts[:2], radius=0.6)
    with pytest.raises(jf.MeshError, match="3D mesh"):
        surface_interpolation(jf.rectangle(0, 0, 1, 1, 1, 1), pts, radius=0.6)


@pytest.mark.slow
def test_cup_holder_bundle_simulates(tmp_path):
    """A compressed cup holder (rim held, dead load on the bottom) solved on a finer mesh (h = 2 mm)
    gives the data; the bundle's model is a coarser cup holder (h = 3 mm) driven by points on the
    bottom face and three rings on the rim, predicting points near the outer wall (at r = 10.8 mm,
    inside both faceted meshes). Measured (load ~36): guide/validate errors 0.0030/0.0027 mm against
    a mean wall displacement of 0.032 mm and noise 1e-3 mm per component; 41 s."""
    from tests.test_cup_holder import BOTTOM, HEIGHT, R_IN, R_OUT, facet_area

    fine = cup_holder(R_IN, R_OUT, HEIGHT, BOTTOM, 2.0)
    mesh, facets = fine.mesh, fine.bottom_outer_facets
    problem = jf.Problem(mesh, "neo-hookean", "solid", fixed=jf.dofs(mesh, fine.sets["rim"]), traction_facets=facets)
    solver = jf.Solver(problem)
    loads = [np.array([0.0, 0.0, F / facet_area(mesh.nodes, facets)]) for F in (1.0, 2.0)]
    U = [np.asarray(solver.solve(problem.params(E=1.0, nu=0.45, traction=t)).u) for t in loads]
    g = np.arange(-9.0, 9.01, 1.5)
    b = np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)
    b = b[np.hypot(*b.T) < 10.3]
    ang = np.linspace(0, 2 * np.pi, 25)[:-1]
    ring = lambda r, z: np.c_[r * np.cos(ang), r * np.sin(ang), np.full(len(ang), z)]  # noqa: E731
    wall = np.vstack([ring(10.8, z)[::2] for z in (2.0, 4.0, 6.0)])
    X = np.vstack([np.c_[b, np.zeros(len(b))], ring(8.2, HEIGHT), ring(9.5, HEIGHT), ring(10.8, HEIGHT), wall])
    roles = ["boundary"] * (len(X) - len(wall)) + ["guide", "validate"] * (len(wall) // 2)
    probe = jf.locate(mesh, X, tol=1e-3)
    rng = np.random.default_rng(0)
    disp = np.stack([np.asarray(probe(u)) for u in U]) + rng.normal(0, 1e-3, (2, len(X), 3))
    root = tmp_path / "cup"
    root.mkdir()
    jf.write_vtu(root / "mesh.vtu", cup_holder(R_IN, R_OUT, HEIGHT, BOTTOM, 3.0).mesh)
    obs = Observations(np.arange(1, len(X) + 1), X, roles, disp)
    write_bundle(root, Bundle(Experiment(name="cup", kind="solid", domain=MeshDomain("mesh.vtu"),
                                         law="neo-hookean", E=1.0, nu=0.45), obs))
    summary = simulate(root, tmp_path / "out", quiet=True)
    scale = np.linalg.norm(disp[:, obs.mask("guide")], axis=2).mean()
    assert summary["guide_error"] < 0.15 * scale and summary["validate_error"] < 0.15 * scale, (summary, scale)
