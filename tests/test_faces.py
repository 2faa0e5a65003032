"""Named faces of a mesh domain: gmsh physical groups of boundary facets (jaxfem.read_mesh ->
Mesh.faces), experiment.toml's domain.faces (a box or a plane), their use as sides (forces, grips),
and where a solid's points are compared (interior points where they are).

Meshes are boxes of sizes drawn under a seed; a file's groups are written in another node order
than the mesh's own facets (gmsh's), so reading must match them by their corners.
"""

from __future__ import annotations

import warnings

import meshio
import numpy as np
import pytest

import jaxfem as jf
from refine.bundle.experiment import Experiment, MeshDomain
from refine.bundle.sides import with_domain_faces
from refine.exceptions import ExperimentError, ObservationError
from refine.model.boundary import face_facets, place_surface_points, side_nodes


def _rows(f):
    return {tuple(sorted(r)) for r in np.asarray(f).tolist()}


def _box(seed, element="tet10"):
    rng = np.random.default_rng(seed)
    L, W, H = rng.uniform(2.0, 5.0, 3)
    return jf.box(0.0, 0.0, 0.0, L, W, H, 3, 2, 2, element), (L, W, H)


def _write_msh(path, mesh, groups, dim_names):
    """``mesh`` as gmsh 2.2 with facet groups ``{name: facets}`` (corners rotated, as another code would)."""
    facet = jf.elements.get_element(mesh.el.facet)
    rot = {"triangle6": [1, 2, 0, 4, 5, 3], "triangle": [1, 2, 0], "line3": [1, 0, 2], "line": [1, 0]}[facet.meshio]
    blocks, tags = [(mesh.el.meshio, mesh.cells)], [np.full(mesh.n_cells, 100)]
    field = {"body": np.array([100, mesh.dim])}
    for k, (name, f) in enumerate(groups.items(), start=1):
        blocks.append((facet.meshio, np.asarray(f)[:, rot]))
        tags.append(np.full(len(f), k))
        field[name] = np.array([k, dim_names])
    m = meshio.Mesh(np.c_[mesh.nodes, np.zeros((mesh.n_nodes, 3 - mesh.dim))], blocks,
                    cell_data={"gmsh:physical": tags, "gmsh:geometrical": tags}, field_data=field)
    m.write(path, file_format="gmsh22", binary=False)


def test_read_mesh_keeps_the_physical_groups_of_boundary_facets_as_faces(tmp_path):
    mesh, (L, W, H) = _box(1)
    # facets inside the body: those on the plane x = L / 3 between two layers of cells
    f = mesh.facets()
    on_plane = np.isclose(mesh.nodes[f[:, :3], 0], L / 3).all(axis=1)
    inner = f[on_plane][:4]
    assert len(inner)
    _write_msh(tmp_path / "b.msh", mesh, {"right": mesh.side_facets("left"), "loaded": mesh.side_facets("right"),
                                          "interface": inner}, 2)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        back = jf.read_mesh(tmp_path / "b.msh")
    assert any("interface" in str(w.message) and "not on the mesh's boundary" in str(w.message) for w in caught)
    assert sorted(back.faces) == ["loaded", "right"] and back.region_names == {100: "body"}
    np.testing.assert_allclose(back.nodes, mesh.nodes)
    assert _rows(back.faces["loaded"]) == _rows(mesh.side_facets("right"))
    # the mesh's own facet rows (outward order), not the file's rotated ones
    own = {tuple(r) for r in back.boundary_facets().tolist()}
    assert all(tuple(r) in own for r in back.faces["loaded"].tolist())
    # a named face wins over the bounding box's side of that name; other bbox sides keep meaning bbox
    np.testing.assert_array_equal(back.side("right"), mesh.side("left"))
    np.testing.assert_array_equal(back.side("top"), mesh.side("top"))
    assert _rows(back.side_facets("right")) == _rows(mesh.side_facets("left"))
    assert back.side_names()[:2] == ["right", "loaded"] and "front" in back.side_names()
    with pytest.raises(jf.MeshError, match=r"unknown side 'grip'.*'loaded'"):
        back.side("grip")


def test_a_triangle_mesh_reads_its_physical_curves_as_faces(tmp_path):
    rng = np.random.default_rng(2)
    Lx, Ly = rng.uniform(3.0, 6.0, 2)
    mesh = jf.rectangle(0.0, 0.0, Lx, Ly, 4, 3, "tri6")
    _write_msh(tmp_path / "p.msh", mesh, {"clamp": mesh.side_facets("bottom")}, 1)
    back = jf.read_mesh(tmp_path / "p.msh")
    assert back.element == "tri6" and list(back.faces) == ["clamp"]
    np.testing.assert_array_equal(back.side("clamp"), mesh.side("bottom"))


def test_experiment_toml_names_faces_by_a_box_or_a_plane():
    mesh, (L, W, H) = _box(3)
    table = {"experiment": {"name": "x"}, "model": {"kind": "solid", "domain": {
        "mesh": "m.msh", "faces": {"grip": {"box": [-0.01, -0.01, -0.01, L / 2, 0.01, H + 0.01]},
                                   "end": {"plane": [2.0, 0.0, 0.0, 2.0 * L], "tol": 1e-6}},
        "boundary_faces": ["end"]}}, "material": {"law": "neo-hookean", "E": 1.0, "nu": 0.3}}
    exp = Experiment.from_toml(table)
    assert Experiment.from_toml(exp.to_toml()) == exp and exp.domain.boundary_faces == ("end",)
    m = with_domain_faces(mesh, exp.domain.faces)
    X = mesh.nodes
    bottom = mesh.side_facets("bottom")  # y = 0
    expect = bottom[(X[bottom][..., 0] <= L / 2 + 0.01).all(axis=1)]
    assert len(expect) and _rows(m.faces["grip"]) == _rows(expect)
    assert _rows(m.faces["end"]) == _rows(mesh.side_facets("right"))
    np.testing.assert_array_equal(side_nodes(m, exp.domain, "end"), mesh.side("right"))
    # the model resolves them from the domain on a mesh without them too
    assert _rows(face_facets(mesh, exp.domain, "grip")) == _rows(expect)
    np.testing.assert_array_equal(side_nodes(mesh, exp.domain, "left"), mesh.side("left"))


def test_a_face_that_selects_nothing_or_is_unknown_is_an_error_naming_it():
    mesh, (L, W, H) = _box(4)
    dom = MeshDomain("m.msh", faces={"ghost": {"box": [L + 1, 0, 0, L + 2, W, H]}, "end": {"plane": [1, 0, 0, L]}})
    with pytest.raises(ExperimentError, match=r"domain.faces.ghost .*selects no boundary facet.*'end'.*'left'"):
        with_domain_faces(mesh, dom.faces)
    dom = MeshDomain("m.msh", faces={"end": {"plane": [1, 0, 0, L]}})
    with pytest.raises(ObservationError, match=r"unknown face 'grip'.*\['end', 'left'"):
        side_nodes(mesh, dom, "grip")
    with pytest.raises(ExperimentError, match="has 3 numbers, but the mesh is 3D: give 4"):
        with_domain_faces(mesh, MeshDomain("m.msh", faces={"e": {"plane": [1, 0, L]}}).faces)
    for bad, what in (({"e": {"box": [0, 0, 1]}}, "6 finite numbers"), ({"e": {"disc": [0]}}, "one of box"),
                      ({"e": {"plane": [0, 0, 0, 1]}}, "normal"), ({"e": {"plane": [1, 0, 0, 1], "tol": -1}}, "tol")):
        with pytest.raises(ExperimentError, match=what):
            MeshDomain("m.msh", faces=bad)
    with pytest.raises(ExperimentError, match="go with a mesh domain"):
        Experiment.from_toml({"experiment": {"name": "x"}, "model": {"kind": "plane-stress", "domain": {
            "rectangle": [0, 0, 1, 1], "faces": {"e": {"plane": [1, 0, 1]}}}},
            "material": {"law": "neo-hookean", "E": 1.0, "nu": 0.3}})


def test_grips_take_a_named_face():
    from refine.correspond.model import _side

    mesh, (L, W, H) = _box(5)
    m = with_domain_faces(mesh, MeshDomain("m.msh", faces={"jaw": {"plane": [0, 0, 1, H]}}).faces)
    np.testing.assert_array_equal(_side(m, "jaw"), mesh.side("front"))
    with pytest.raises(Exception, match=r"unknown side 'claw'.*jaw"):
        _side(m, "claw")


def test_solid_points_inside_stay_where_they_are_and_surface_points_go_onto_the_surface():
    """Interior points (DVC) are compared at their own position; boundary points at their foot on
    the surface; another point just outside is projected, one far outside refused by name."""
    from jaxfem.surface import project_to_surface

    mesh, (L, W, H) = _box(6)
    rng = np.random.default_rng(6)
    inside = rng.uniform([0.1, 0.1, 0.1], [L - 0.1, W - 0.1, H - 0.1], (20, 3))
    surface = rng.uniform([0, 0, 0], [L, W, H], (8, 3))
    surface[:, 2] = H + rng.normal(0.0, 0.01, 8)  # on the top (z = H), off it by noise either way
    near = np.array([[L / 2, W / 2, -0.02]])  # a guide point 0.02 below the bottom
    pts = np.vstack([inside, surface, near])
    boundary = np.r_[np.zeros(20, bool), np.ones(8, bool), False]
    ids = np.arange(100, 100 + len(pts))
    p = place_surface_points(mesh, pts, boundary, ids, tolerance=0.05)
    np.testing.assert_array_equal(p.positions[:20], inside)
    np.testing.assert_allclose(p.positions[20:28, 2], H, atol=1e-12)
    np.testing.assert_allclose(p.positions[20:28, :2], surface[:, :2], atol=1e-12)
    np.testing.assert_allclose(p.offsets[20:28], np.abs(surface[:, 2] - H), atol=1e-12)
    assert project_to_surface(mesh, p.positions[28:])[1][0] < 1e-12  # projected onto the bottom
    pts[3] = [L / 2, W / 2, H + 0.5]  # an "interior" point half a unit above the body
    with pytest.raises(ObservationError, match=r"1 points lie outside the mesh.*point 103"):
        place_surface_points(mesh, pts, boundary, ids, tolerance=0.05)


def test_a_cloud_model_holds_and_grips_the_faces_experiment_toml_names(tmp_path):
    from refine.correspond.model import CloudModel, Grips

    mesh, (L, W, H) = _box(7)
    jf.write_vtu(tmp_path / "m.vtu", mesh)
    exp = Experiment(name="x", kind="solid", law="neo-hookean", E=1.0, nu=0.3, domain=MeshDomain(
        "m.vtu", faces={"base": {"plane": [0, 1, 0, 0]}, "jaw": {"box": [L / 2, -1, -1, L + 1, W + 1, H + 1]}}))
    model = CloudModel(exp, Grips(clamped=("base",), gripped=("jaw",)), root=tmp_path)
    X = model.mesh.nodes
    np.testing.assert_array_equal(model.clamp, mesh.side("bottom"))
    jaw = np.unique(model.mesh.faces["jaw"])
    assert np.all(X[jaw, 0] >= L / 2 - 1e-12) and len(jaw) > len(mesh.side("right"))
    np.testing.assert_array_equal(model.grip_nodes[0], np.setdiff1d(jaw, model.clamp))


def test_a_tet4_file_keeps_its_faces_through_to_quadratic(tmp_path):
    mesh, _ = _box(8, "tet4")
    _write_msh(tmp_path / "t.msh", mesh, {"end": mesh.side_facets("front")}, 2)
    back = jf.read_mesh(tmp_path / "t.msh")
    assert _rows(back.faces["end"]) == _rows(mesh.side_facets("front"))
    quad = jf.to_quadratic(back)
    assert quad.element == "tet10" and quad.faces["end"].shape == (len(mesh.side_facets("front")), 6)
    assert _rows(quad.faces["end"]) == _rows(quad.side_facets("front"))
