"""Meshes that follow elliptic / rectangular holes and inclusions, and the differentiable morph."""

import re

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxfem.exceptions import InvertedElementError, MeshError
from jaxfem.mesh import check_orientation
from jaxfem.mesher import domain, plate
from jaxfem.shapes import Ellipse, Polygon, Rect, check_morph, curve_nodes, min_angles, morph

W, H = 40.0, 30.0
HOLE = Ellipse(12, 15, 6, 4, 0.3)
INCL = Ellipse(28, 14, 5, 7, -0.4)
BAR = Rect(20, 25, 26, 28, 0.2)


def sample_plate(h, element="tri3"):
    return plate(0, 0, W, H, h, holes=[HOLE], inclusions={"soft": INCL, "bar": BAR}, element=element)


def area_errors(mesh):
    """Relative errors of the hole area (through the plate area), the inclusion and the bar."""
    v = mesh.volumes()
    return np.array([abs(W * H - v.sum() - HOLE.area) / HOLE.area,
                     abs(v[mesh.regions == 1].sum() - INCL.area) / INCL.area,
                     abs(v[mesh.regions == 2].sum() - BAR.area) / BAR.area])


def test_areas_converge_as_h_squared():
    hs = np.array([1.6, 0.8, 0.4])
    errors = np.array([area_errors(sample_plate(h)) for h in hs])
    rates = np.log2(errors[:-1, :2] / errors[1:, :2])
    assert (rates > 1.75).all(), rates  # O(h^2): the error drops about 4x when h halves
    assert (errors[:, :2] < 0.01 * hs[:, None] ** 2).all(), errors
    assert errors[:, 2].max() < 1e-12  # straight sides are exact


def test_tri6_puts_mid_edge_nodes_on_curves_and_converges_faster():
    e3, e6 = area_errors(sample_plate(1.0)), area_errors(sample_plate(1.0, "tri6"))
    assert (e6[:2] < 1e-2 * e3[:2]).all(), (e3, e6)


@pytest.mark.parametrize("element", ["tri3", "tri6", "quad4"])
def test_boundary_and_interfaces_lie_on_the_curves(element):
    mesh = sample_plate(1.0, element)
    check_orientation(mesh)
    for shape in (HOLE, INCL):
        on = curve_nodes(mesh, shape)
        r = np.linalg.norm(shape.to_unit(mesh.nodes[on]), axis=1)
        assert np.abs(r - 1).max() < 1e-12
        assert len(on) >= 30  # about perimeter / h nodes
    x = mesh.nodes[mesh.boundary_nodes()]
    on_outline = (np.abs(x[:, 0]) < 1e-9) | (np.abs(x[:, 0] - W) < 1e-9) | (np.abs(x[:, 1]) < 1e-9) \
        | (np.abs(x[:, 1] - H) < 1e-9)
    on_hole = np.abs(np.linalg.norm(HOLE.to_unit(x), axis=1) - 1) < 1e-12
    assert (on_outline | on_hole).all()
    # every node shared by the inclusion and the background lies on the inclusion's ellipse
    inner = np.unique(mesh.cells[mesh.regions == 1])
    outer = np.unique(mesh.cells[mesh.regions == 0])
    shared = np.intersect1d(inner, outer)
    assert np.abs(np.linalg.norm(INCL.to_unit(mesh.nodes[shared]), axis=1) - 1).max() < 1e-12
    assert mesh.region_names == {1: "soft", 2: "bar"}


def test_region_areas_and_quality():
    mesh = sample_plate(1.0)
    v = mesh.volumes()
    assert v[mesh.regions == 1].sum() == pytest.approx(np.pi * INCL.rx * INCL.ry, rel=5e-3)
    assert min_angles(mesh).min() > 25.0
    assert min_angles(sample_plate(1.0, "quad4")).min() > 20.0


def test_random_ellipses_all_mesh():
    rng = np.random.default_rng(7)
    for _ in range(8):
        shapes = []
        while len(shapes) < 3:
            a, b = rng.uniform(0.5, 6), rng.uniform(0.3, 4)
            e = Ellipse(rng.uniform(0, W), rng.uniform(0, H), a, b, rng.uniform(0, np.pi))
            big = max(a, b) + 0.5
            if big < e.cx < W - big and big < e.cy < H - big and all(
                    np.hypot(e.cx - o.cx, e.cy - o.cy) > big + max(o.rx, o.ry) for o in shapes):
                shapes.append(e)
        mesh = plate(0, 0, W, H, 1.5, holes=shapes[:1], inclusions=shapes[1:])
        check_orientation(mesh)
        assert min_angles(mesh).min() > 15.0
        v = mesh.volumes()
        assert W * H - v.sum() == pytest.approx(shapes[0].area, rel=0.05)
        for k, s in enumerate(shapes[1:]):
            assert v[mesh.regions == k + 1].sum() == pytest.approx(s.area, rel=0.05)
            on = curve_nodes(mesh, s)
            assert np.abs(np.linalg.norm(s.to_unit(mesh.nodes[on]), axis=1) - 1).max() < 1e-12


def test_sharp_ellipse_is_refined_at_its_ends():
    crack = Ellipse(20, 15, 8, 0.2, 0.4)  # end radius of curvature 0.005
    mesh = plate(0, 0, W, H, 2.0, holes=[crack])
    assert min_angles(mesh).min() > 20.0
    assert W * H - mesh.volumes().sum() == pytest.approx(crack.area, rel=0.02)


def test_other_outlines():
    ell = domain(Polygon([[0, 0], [30, 0], [30, 10], [10, 10], [10, 30], [0, 30]]), 1.5,
                 holes=[Ellipse(5, 5, 2, 1)], inclusions=[Rect(2, 20, 8, 24, 0.3)])
    assert ell.volumes().sum() == pytest.approx(500 - 2 * np.pi, rel=5e-3)
    disc = domain(Ellipse(0, 0, 10, 6), 1.0, holes=[Rect(-2, -1, 2, 1, 0.5)], element="tri6")
    assert disc.volumes().sum() == pytest.approx(60 * np.pi - 8, rel=1e-5)


def test_bad_layouts_raise():
    with pytest.raises(MeshError, match="overlap"):
        plate(0, 0, 10, 10, 1, holes=[Ellipse(5, 5, 3, 3)], inclusions=[Ellipse(7, 5, 2, 1)])
    with pytest.raises(MeshError, match="inside the outline"):
        plate(0, 0, 10, 10, 1, holes=[Ellipse(9, 5, 3, 3)])
    with pytest.raises(MeshError, match="tri3, tri6 or quad4"):
        plate(0, 0, 10, 10, 1, element="hex8")


# ---------------------------------------------------------------- morph
@pytest.fixture(scope="module")
def morphed():
    mesh = sample_plate(2.0)
    return mesh, morph(mesh, [HOLE, INCL])


def test_morph_moves_curves_onto_new_shapes_and_keeps_the_rest(morphed):
    mesh, m = morphed
    assert np.abs(np.asarray(m(m.params0)) - mesh.nodes).max() < 1e-12
    new = Ellipse(13, 14.5, 6.5, 3.5, 0.45)
    x = np.asarray(m(jnp.asarray(m.params0).at[0].set(new.params)))
    on = curve_nodes(mesh, HOLE)
    assert np.abs(np.linalg.norm(new.to_unit(x[on]), axis=1) - 1).max() < 1e-12
    fixed = np.setdiff1d(mesh.boundary_nodes(), on)  # outline, and the untouched inclusions
    fixed = np.union1d(fixed, curve_nodes(mesh, INCL))
    assert np.abs(x[fixed] - mesh.nodes[fixed]).max() == 0.0
    assert check_morph(mesh, x) > 0.3


def test_morph_derivative_matches_central_differences(morphed):
    mesh, m = morphed
    cells = jnp.asarray(mesh.cells)

    def area(params):  # area of the plate minus the hole, through the morphed nodes
        a, b, c = (m(params)[cells[:, k]] for k in range(3))
        return 0.5 * jnp.sum((b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0])

    def smooth(params):
        return jnp.sum(jnp.sin(m(params) / 7.0) ** 2)

    p = m.params0 + 0.1
    for f in (jax.jit(area), jax.jit(smooth)):
        g = np.asarray(jax.grad(f)(p))
        fd = np.zeros_like(g)
        for i in np.ndindex(*g.shape):
            e = np.zeros_like(p)
            e[i] = 1e-5
            fd[i] = (f(p + e) - f(p - e)) / 2e-5
        assert np.abs(g - fd).max() < 1e-6 * max(1.0, np.abs(g).max())
    g = jax.grad(area)(p)
    assert float(g[1, 2]) == pytest.approx(0.0, abs=1e-9)  # an inclusion does not change the area
    # the hole's polygon scales affinely: d(area)/d(rx) = -(hole polygon area) / rx
    assert float(g[0, 2]) == pytest.approx(-(W * H - float(area(p))) / float(p[0, 2]), rel=1e-9)


def test_morph_that_would_invert_raises_and_says_how_much_is_safe(morphed):
    mesh, m = morphed
    change = jnp.zeros((2, 5)).at[0, 0].set(14.0)  # drive the hole into the inclusion
    with pytest.raises(InvertedElementError, match="scale the change") as info:
        check_morph(mesh, m(m.params0 + change))
    scale = float(re.search(r"at most ([0-9.]+)", str(info.value)).group(1))
    assert 0 < scale < 1
    assert check_morph(mesh, m(m.params0 + scale * change)) > 0


def test_morph_band_limits_its_reach():
    mesh = sample_plate(2.0)
    m = morph(mesh, [HOLE], band=3.0)
    x = np.asarray(m(jnp.asarray(m.params0).at[0, 2].add(0.5)))
    moved = np.linalg.norm(x - mesh.nodes, axis=1) > 0
    d = np.linalg.norm(mesh.nodes[moved] - HOLE.to_curve(mesh.nodes[moved]), axis=1)
    assert d.max() < 3.0 + 1e-9
    with pytest.raises(MeshError, match="no curve"):
        morph(mesh, [Ellipse(30, 5, 2, 1)])


@pytest.mark.parametrize("element", ["tri3", "tri6"])
def test_moved_probe_follows_a_morph_and_differentiates(element):
    """A probe located on the reference mesh, moved with the morphed nodes, still points at the
    same physical points (it interpolates the moved coordinates back to them), and its
    derivative in the shape parameters matches central differences."""
    from jaxfem.probe import locate
    from jaxfem.shapes import morph_nodes

    rng = np.random.default_rng(4)
    e = Ellipse(*rng.uniform([40, 25], [60, 35]), *rng.uniform(6, 10, 2), rng.uniform(0, np.pi))
    m = plate(0, 0, 100, 60, 4.0, inclusions=[e], element=element)
    mo = morph(m, [e])
    pts = rng.uniform([5, 5], [95, 55], (200, 2))
    probe = locate(m, pts)
    new = jnp.asarray(e.params[None] + rng.uniform(-1, 1, (1, 5)) * [1.5, 1.5, 1.0, 1.0, 0.1])
    X = morph_nodes(mo.nodes0, new, mo.params0, mo.weights)
    assert float(jnp.abs(probe.moved(X, pts)(X) - pts).max()) < 1e-9
    field = jnp.asarray(np.sin(m.nodes[:, :1] / 7.0))  # a field carried by the moving nodes

    def f(q):
        return jnp.sum(probe.moved(morph_nodes(mo.nodes0, q, mo.params0, mo.weights), pts)(field))

    d, h = jnp.asarray(rng.standard_normal((1, 5)) * [1, 1, 1, 1, 0.05]), 1e-5
    fd = (f(new + h * d) - f(new - h * d)) / (2 * h)
    assert abs(float(jnp.sum(jax.grad(f)(new) * d)) - float(fd)) <= 1e-6 * max(1.0, abs(float(fd)))
