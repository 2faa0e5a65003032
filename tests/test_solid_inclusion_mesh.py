"""The graded box an inclusion is refitted on (jaxfem.graded, refine.solid.inclusion_mesh): ticks
fine over a focus drawn at random, coarse elsewhere, a conforming tet10 box on them, the
inclusion's smooth share on such a mesh, and the focus taken from a fitted ellipsoid."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

import jaxfem as jf
from examples.cup_holder import cup_holder
from jaxfem.exceptions import MeshError
from jaxfem.graded import graded_box, graded_ticks


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_graded_ticks_are_fine_over_the_focus_and_grow_to_coarse(seed):
    rng = np.random.default_rng(seed)
    lo, hi = 0.0, float(rng.uniform(20, 50))
    a, b = sorted(rng.uniform(lo - 2, hi + 2, 2))
    fine, coarse, growth = float(rng.uniform(1.0, 2.5)), float(rng.uniform(3.0, 6.0)), 1.6
    t = graded_ticks(lo, hi, (a, b), fine, coarse, growth)
    d = np.diff(t)
    assert t[0] == lo and t[-1] == hi and (d > 0).all()
    inside = (t[:-1] >= max(a, lo) - 1e-9) & (t[1:] <= min(b, hi) + 1e-9)
    assert d[inside].max() <= fine + 1e-9 and d.max() <= max(coarse, growth * fine) * (1 + 1e-9)
    assert d.max() > fine or (b - a) >= hi - lo - 2 * fine  # coarser away from a focus that leaves room
    assert d.min() >= 0.5 * fine * (1 - 1e-9) or len(d) == 1
    for edge in (graded_ticks(0.0, 20.0, (3.0, 19.995), 2.5, 5.0), graded_ticks(0.0, 20.0, (0.01, 12.0), 2.5, 5.0)):
        assert np.diff(edge).min() > 1.0  # a focus at an end leaves no sliver cell
    with pytest.raises(MeshError, match="fine <= coarse"):
        graded_ticks(lo, hi, (a, b), 3.0, 2.0)


def test_graded_box_is_a_conforming_box_mesh_on_its_ticks():
    rng = np.random.default_rng(4)
    ticks = [np.r_[0.0, np.sort(rng.uniform(0.1, L - 0.1, n)), L] for L, n in ((8.0, 4), (4.0, 2), (3.0, 3))]
    m = graded_box(ticks)
    jf.check_orientation(m)
    assert m.element == "tet10" and np.isclose(m.volumes().sum(), 96.0)
    assert m.n_cells == 6 * 5 * 3 * 4
    edges = m.cells[:, [4, 5, 6, 7, 8, 9]], m.cells[:, [0, 1, 2, 0, 1, 2]], m.cells[:, [1, 2, 0, 3, 3, 3]]
    assert np.allclose(m.nodes[edges[0]], 0.5 * (m.nodes[edges[1]] + m.nodes[edges[2]]))  # straight edges
    assert len(m.boundary_facets()) == 2 * 2 * (5 * 3 + 5 * 4 + 3 * 4)  # conforming: no inner facet left open
    uniform = graded_box([np.linspace(0, 8, 5), np.linspace(0, 4, 3), np.linspace(0, 3, 4)])
    same = jf.box(0, 0, 0, 8, 4, 3, 4, 2, 3, element="tet10")
    assert np.allclose(uniform.nodes, same.nodes) and (uniform.cells == same.cells).all()
    with pytest.raises(MeshError, match="increasing"):
        graded_box([np.array([0.0, 2.0, 1.0]), ticks[1], ticks[2]])


def region(rng, lo, hi):
    R = np.linalg.qr(rng.standard_normal((3, 3)))[0]
    return SimpleNamespace(centroid=rng.uniform(lo + 0.35 * (hi - lo), hi - 0.35 * (hi - lo)),
                           axes=rng.uniform(0.1, 0.2, 3) * (hi - lo).min(), rotation=R)


def test_focused_mesh_is_fine_around_the_region_only_and_none_off_a_box():
    from refine.solid.inclusion_mesh import FocusedMesh, extent, focused_mesh

    body = jf.box(0, 0, 0, 40, 20, 20, 10, 5, 5, element="tet10")
    reg = region(np.random.default_rng(7), *body.bounds())
    cfg = FocusedMesh(fine=2.0, coarse=5.0)
    m = focused_mesh(body, [reg], cfg)
    size = np.cbrt(6 * m.volumes())
    a, b = extent(reg.centroid, reg.axes, reg.rotation)
    near = ((m.centroids() > a) & (m.centroids() < b)).all(1)
    assert near.any() and size[near].max() <= 2.0 + 1e-9 and size.max() > 3.0
    assert np.isclose(m.volumes().sum(), 16000.0) and m.n_cells < 0.5 * 6 * 20 * 10 * 10
    assert focused_mesh(body, [], cfg) is None
    assert focused_mesh(cup_holder(8.0, 11.0, 8.0, 3.0, 4.0).mesh, [reg], cfg) is None


def test_the_inclusions_share_holds_its_volume_on_a_graded_mesh():
    from refine.solid.inclusion import EllipsoidModulus, cell_size
    from refine.solid.inclusion_mesh import FocusedMesh, focused_mesh

    body = jf.box(0, 0, 0, 24, 12, 12, 6, 3, 3, element="tet10")
    rng = np.random.default_rng(5)
    reg = region(rng, *body.bounds())
    reg.axes = rng.uniform(0.25, 0.3, 3) * 12.0
    m = focused_mesh(body, [reg], FocusedMesh(fine=2.0, coarse=4.0))
    M = reg.rotation @ np.diag(reg.axes) @ reg.rotation.T
    sizes = np.cbrt(6 * m.volumes())
    p = EllipsoidModulus(m, reg.centroid, M, 1.0, 0.1 * sizes[:, None], 0.1, 0.0, 0.3)
    f = np.asarray(p.fraction(np.asarray(p.z0)))
    assert abs((f * m.volumes()).sum() / (4 / 3 * np.pi * np.prod(reg.axes)) - 1) < 0.02
    assert sizes[f > 0.5].max() <= 2.0 + 1e-9 < sizes.max()  # the inclusion's cells are the fine ones
    assert np.isclose(np.cbrt(6 * body.volumes()), cell_size(body)).all()  # a uniform box: one width, as before


def test_focus_of_a_fitted_shape_pads_its_axes():
    from refine.solid.inclusion import EllipsoidShape
    from refine.solid.inclusion_mesh import focus_of

    s = EllipsoidShape((10.0, 5.0, 6.0), (4.0, 3.0, 2.0), tuple(map(tuple, np.eye(3))), 3.0)
    f = focus_of(s, pad=1.25)
    assert np.allclose(f.axes, [5.0, 3.75, 2.5]) and np.allclose(f.centroid, s.centre)


def test_the_diagnosis_refits_on_a_graded_box_by_default_and_keeps_a_non_box_as_it_is():
    from refine.solid.inclusion import EllipsoidShape
    from refine.solid.inclusion_diagnosis import InclusionConfig
    from refine.solid.inclusion_mesh import FocusedMesh, refit_focused

    assert InclusionConfig().focus == FocusedMesh() and InclusionConfig().fit_mesh is None
    shape = EllipsoidShape((8.0, 0.0, 5.0), (2.0, 1.5, 1.0), tuple(map(tuple, np.eye(3))), 3.0)
    cup = SimpleNamespace(model=SimpleNamespace(mesh=cup_holder(8.0, 11.0, 8.0, 3.0, 4.0).mesh), shapes=[shape])
    assert refit_focused(cup, None, None, 0.01) == (None, None)  # no solve: nothing to grade


def test_points_on_a_graded_box_are_located_beyond_the_nearest_fine_centroids():
    from scipy.spatial import cKDTree

    from jaxfem.probe import find_cells_among

    m = graded_box([graded_ticks(0, 40, (22, 36), 2.5, 5, 1.6), graded_ticks(0, 20, (5, 17), 2.5, 5, 1.6),
                    graded_ticks(0, 20, (8, 20), 2.5, 5, 1.6)])
    rng = np.random.default_rng(0)
    P = np.c_[rng.uniform(0, 40, 4000), rng.uniform(0, 20, 4000), np.full(4000, 20.0)]
    assert (find_cells_among(m, P, cKDTree(m.centroids()), 24)[2] > 1e-2).any()  # 24 candidates miss some
    probe = jf.locate(m, P, tol=1e-6)  # the fallback finds them
    assert np.allclose(probe(np.asarray(m.nodes)), P)
