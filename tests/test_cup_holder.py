"""The parametric 3D cup holder (examples.cup_holder, on jaxfem.wall): geometry, named sets, and a forward solve of the
compressed cup holder (rim held, a uniform dead load on the bottom's outer face), with and without
a through-thickness elliptic hole in the bottom drawn at random under a seed."""

import numpy as np
import pytest

import jaxfem as jf
from examples.cup_holder import cup_bottom, cup_holder

R_IN, R_OUT, HEIGHT, BOTTOM = 8.0, 11.0, 8.0, 3.0  # mm
H = 3.0  # element size, mm


def random_hole(seed):
    """An elliptic hole in the floor: centre, semi-axes and angle drawn under ``seed``."""
    rng = np.random.default_rng(seed)
    rx, ry = rng.uniform(2.0, 3.5), rng.uniform(1.5, 2.5)
    r, phi = rng.uniform(0.0, R_IN - rx - 1.5), rng.uniform(0, 2 * np.pi)
    return jf.Ellipse(r * np.cos(phi), r * np.sin(phi), rx, ry, rng.uniform(0, np.pi))


def facet_area(X, facets):
    a, b, c = X[facets[:, 0]], X[facets[:, 1]], X[facets[:, 2]]
    return 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1).sum()


@pytest.mark.parametrize("seed", [None, 3])
def test_cup_holder_geometry_and_sets(seed):
    hole = None if seed is None else random_hole(seed)
    cup = cup_holder(R_IN, R_OUT, HEIGHT, BOTTOM, H, hole=hole)
    mesh, X = cup.mesh, cup.mesh.nodes
    assert mesh.element == "tet10" and mesh.jacobian_dets().min() > 0
    # volume of the solid: within the polygonal approximation of the circles (chords of ~h)
    vol = np.pi * R_OUT**2 * HEIGHT - np.pi * R_IN**2 * (HEIGHT - BOTTOM) - (0 if hole is None else hole.area * BOTTOM)
    assert mesh.volumes().sum() == pytest.approx(vol, rel=0.03)
    r, z = np.hypot(X[:, 0], X[:, 1]), X[:, 2]
    s = cup.sets
    assert np.allclose(z[s["rim"]], HEIGHT) and np.all(r[s["rim"]] >= R_IN - 0.2)
    assert np.allclose(z[s["bottom_outer"]], 0.0) and np.allclose(z[s["bottom_inner"]], BOTTOM)
    assert np.all(np.abs(r[s["wall_inner"]] - R_IN) < 0.2) and np.all(z[s["wall_inner"]] >= BOTTOM)
    assert np.all(np.abs(r[s["wall_outer"]] - R_OUT) < 0.2)
    # the loaded face: the disk r < R_OUT minus the hole
    area = facet_area(X, cup.bottom_outer_facets)
    assert area == pytest.approx(np.pi * R_OUT**2 - (0 if hole is None else hole.area), rel=0.03)
    if hole is None:
        assert s["hole"].size == 0
    else:
        on = s["hole"]
        assert on.size > 0 and np.all(z[on] <= BOTTOM + 1e-9)
        d = np.linalg.norm(hole.to_curve(X[on, :2]) - X[on, :2], axis=1)
        assert d.max() < 0.05 * max(hole.rx, hole.ry)  # mid-edge nodes on chords


def test_cup_holder_bad_input():
    with pytest.raises(jf.MeshError, match="r_in < r_out"):
        cup_holder(11.0, 8.0, HEIGHT, BOTTOM, H)
    with pytest.raises(jf.MeshError, match="inside the floor"):
        cup_holder(R_IN, R_OUT, HEIGHT, BOTTOM, H, hole=jf.Ellipse(6.0, 0.0, 3.0, 2.0))
    with pytest.raises(jf.MeshError, match="tet4 or tet10"):
        cup_holder(R_IN, R_OUT, HEIGHT, BOTTOM, H, element="hex8")


def compress(hole, force=2.0, E=1.0, nu=0.45):
    """Rim held, total dead load ``force`` (N) upward on the bottom's outer face (E in MPa):
    ``(cup, solver, theta, solution)``."""
    cup = cup_holder(R_IN, R_OUT, HEIGHT, BOTTOM, H, hole=hole)
    mesh, facets = cup.mesh, cup.bottom_outer_facets
    problem = jf.Problem(mesh, "neo-hookean", "solid", fixed=jf.dofs(mesh, cup.sets["rim"]), traction_facets=facets)
    solver = jf.Solver(problem)
    theta = problem.params(E=E, nu=nu, traction=np.array([0.0, 0.0, force / facet_area(mesh.nodes, facets)]))
    return cup, solver, theta, solver.solve(theta)


@pytest.mark.slow  # a 3D tet10 solve, ~40 s on 2 cores (the guide: 3D checks are slow)
def test_compressed_cup_holder_hole_makes_the_bottom_softer():
    lift = {}
    for seed in (None, 5):
        cup, solver, theta, sol = compress(None if seed is None else random_hole(seed))
        u = np.asarray(sol.u)
        moved = cup.mesh.nodes + u
        assert cup.mesh.jacobian_dets(moved).min() > 0  # no inverted element
        F = np.asarray(jf.deformation_gradient(solver, sol.u, theta))
        assert np.linalg.det(F).min() > 0.5
        # the rim carries the whole load: reaction = - applied force
        assert np.asarray(solver.reactions(sol.u, theta)) == pytest.approx([0.0, 0.0, -2.0], abs=1e-8)
        lift[seed] = u[cup.sets["bottom_inner"], 2].mean()
        assert 0.0 < lift[seed] < 0.5 * HEIGHT  # pushed in, not through the rim
    assert lift[5] > 1.1 * lift[None], lift


@pytest.mark.parametrize("seed", [5])
def test_cup_holder_hole_h_resolves_a_sharp_hole(seed):
    """``hole_h`` sizes the elements along the hole's curve: a random elongated hole (ends sharper
    than the mesh's h) gets edges along its curve below its smallest radius of curvature, the mesh
    stays valid and closed, and the refinement stays near the hole."""
    rng = np.random.default_rng(seed)
    b = rng.uniform(1.0, 1.4)
    a = b * rng.uniform(1.5, 1.9)
    r, phi = rng.uniform(0.0, R_IN - a - 1.0), rng.uniform(0, 2 * np.pi)
    hole = jf.Ellipse(r * np.cos(phi), r * np.sin(phi), a, b, rng.uniform(0, np.pi))
    rho, h = b * b / a, 1.5
    assert rho < 0.75 * h  # the case this is for: ends sharper than the mesh
    plain = cup_holder(R_IN, R_OUT, HEIGHT, BOTTOM, h, hole=hole, element="tet4", layers=1)
    fine = cup_holder(R_IN, R_OUT, HEIGHT, BOTTOM, h, hole=hole, element="tet4", layers=1, hole_h=0.5 * rho)
    mesh = fine.mesh
    assert mesh.jacobian_dets().min() > 0
    f = mesh.boundary_facets()[:, :3]
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    assert np.all(np.unique(e, axis=0, return_counts=True)[1] == 2)  # a closed surface
    vol = np.pi * R_OUT**2 * HEIGHT - np.pi * R_IN**2 * (HEIGHT - BOTTOM) - hole.area * BOTTOM
    assert mesh.volumes().sum() == pytest.approx(vol, rel=0.03)

    def curve_edges(cup):  # the plan's boundary edges on the hole's curve: (lengths, midpoints)
        P, t = cup.plan.nodes, cup.plan.cells
        ed = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1)
        u, n = np.unique(ed, axis=0, return_counts=True)
        u = u[n == 1]
        on = np.abs(np.linalg.norm(hole.to_unit(P[u].reshape(-1, 2)), axis=1) - 1).reshape(-1, 2).max(1) < 1e-9
        return np.linalg.norm(P[u[on, 0]] - P[u[on, 1]], axis=1)

    assert curve_edges(plain).max() > rho  # without it the flanks' edges are longer than the ends' radius
    assert curve_edges(fine).max() < rho
    assert len(curve_edges(fine)) >= 2 * np.pi * np.sqrt(0.5 * (a * a + b * b)) / (0.5 * rho) * 0.9
    # graded back to h away from the hole: the plan grows by what the hole's neighbourhood needs
    assert fine.plan.n_cells < 1.6 * plain.plan.n_cells
    with pytest.raises(jf.MeshError, match="hole_h"):
        cup_holder(R_IN, R_OUT, HEIGHT, BOTTOM, h, hole=hole, element="tet4", hole_h=0.0)


def test_the_datas_hole_is_the_drawn_ellipse_to_a_fraction_of_a_percent():
    """The data's mesh cuts the hole as a polygon: at the data's h 0.8 alone it kept 97-98.5 % of the
    drawn ellipse (a bias of the size of the 2 % target); cut along the hole at
    ``data_hole_h`` it keeps more than 99.5 % (seeds drawn as the benchmark draws them)."""
    from examples.cup_holder.synthetic import CupGeometry, data_hole_h, random_hole

    g = CupGeometry()

    def volume(mesh):
        x = mesh.nodes[mesh.cells[:, :4]]
        return np.abs(np.linalg.det(x[:, 1:] - x[:, :1])).sum() / 6

    for seed in (6,):  # the most elongated hole of the benchmark's seeds
        hole = random_hole(g, seed)
        kept = [(volume(cup_bottom(g.r_in, g.r_out, g.bottom, 0.8, layers=1).mesh)
                 - volume(cup_bottom(g.r_in, g.r_out, g.bottom, 0.8, hole, layers=1, hole_h=hh).mesh))
                / (g.bottom * hole.area) for hh in (None, data_hole_h(hole, 0.8))]
        assert kept[0] < 0.99 and kept[1] > 0.995, (seed, kept)
