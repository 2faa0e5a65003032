"""``nonrigid mesh``: a STEP bracket (made here with gmsh's OpenCASCADE kernel) meshed into tet10
with named faces, a bundle on that mesh that ``nonrigid simulate`` runs; a planar ``.geo`` into
tri6 with its physical groups' names; an STL; the errors (gmsh missing, an unknown face, a
non-planar surface, a mesh format that would lose the names)."""

from __future__ import annotations

import sys

import numpy as np
import pytest

gmsh = pytest.importorskip("gmsh", reason="nonrigid mesh needs gmsh (pip install 'nonrigid[mesh]')")

import jaxfem as jf  # noqa: E402
from refine.bundle import Bundle, Experiment, MeshDomain, Observations, write_bundle  # noqa: E402
from refine.bundle.mesher import MeshingError, mesh_faces, mesh_geometry  # noqa: E402
from refine.cli import main, simulate  # noqa: E402

# the L-bracket: a 40 x 10 x 20 arm along x and a 10 x 30 x 20 leg along y, a hole of radius R
# through the arm along y at (XC, ZC)
R, XC, ZC = 4.0, 25.0, 10.0
# the surface: top and bottom (L-shaped), the leg's back and end, the arm's end, the inner corner's
# face x = 10, the arm's two faces y = 0 and y = 10 less the hole, the hole's wall
AREA = 2 * 600 + 600 + 200 + 200 + 400 + (800 - np.pi * R**2) + (600 - np.pi * R**2) + 2 * np.pi * R * 10


def _bracket_step(path):
    gmsh.initialize(readConfigFiles=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        occ = gmsh.model.occ
        body, _ = occ.fuse([(3, occ.addBox(0, 0, 0, 40, 10, 20))], [(3, occ.addBox(0, 0, 0, 10, 30, 20))])
        occ.cut(body, [(3, occ.addCylinder(XC, -1, ZC, 0, 12, 0, R))])
        occ.synchronize()
        gmsh.write(str(path))
    finally:
        gmsh.finalize()
    return path


@pytest.fixture(scope="module")
def bracket(tmp_path_factory):
    return _bracket_step(tmp_path_factory.mktemp("geometry") / "bracket.step")


def _face_at(faces, axis, value):
    [name] = [n for n, f in faces.items() if abs(f["centroid"][axis] - value) < 1e-6 and f["area"] > 0]
    return name


def test_step_bracket_meshes_into_a_bundle_that_simulate_runs(bracket, tmp_path, capsys):
    first = mesh_geometry(bracket, 4.0, tmp_path / "probe.msh")
    assert first.element == "tet10" and first.regions == ["body"]
    assert all(n.startswith("face_") for n in first.faces) and len(first.faces) == 9  # 6 + 2 inner + the hole
    # the faces are the geometry's: planar ones exactly, the hole's wall within the chords' error
    assert sum(f["area"] for f in first.faces.values()) == pytest.approx(AREA, rel=0.01)
    fixed, load = _face_at(first.faces, 0, 0.0), _face_at(first.faces, 0, 40.0)  # the leg's end, the arm's
    assert first.faces[fixed]["area"] == pytest.approx(30 * 20, rel=1e-12)

    bundle = tmp_path / "bundle"
    bundle.mkdir()
    code = main(["mesh", str(bracket), "--size", "4", "--out", str(bundle / "bracket.msh"),
                 "--name", f"{fixed}=fixed", "--name", f"{load}=load"])
    assert code == 0
    printed = capsys.readouterr().out
    assert "tet10" in printed and "fixed" in printed and "load" in printed and fixed not in printed.split()
    nodes = mesh_faces(bundle / "bracket.msh")
    assert {"fixed", "load"} <= set(nodes) and np.allclose(nodes["fixed"][:, 0], 0) and np.allclose(nodes["load"][:, 0], 40)
    mesh = jf.read_mesh(bundle / "bracket.msh")
    assert mesh.element == "tet10" and mesh.n_cells == first.n_cells and mesh.region_names == {1: "body"}

    # the smallest solid bundle: the fixed face held, the arm's end pushed down, the top of the arm observed
    rng = np.random.default_rng(5)
    dz = -0.2
    top = nodes[_face_at(first.faces, 2, 20.0)]
    top = top[(top[:, 0] > 12) & (top[:, 0] < 38)]
    top = top[rng.choice(len(top), 12, replace=False)]
    X = np.vstack([nodes["fixed"], nodes["load"], top])
    roles = np.array(["boundary"] * (len(nodes["fixed"]) + len(nodes["load"])) + ["guide"] * 8 + ["validate"] * 4)
    U = np.zeros((1, len(X), 3))
    U[0, len(nodes["fixed"]): len(nodes["fixed"]) + len(nodes["load"]), 2] = dz
    U[0, -len(top):, 2] = dz * (top[:, 0] - 10) / 30  # a guess; the model's prediction is compared to it
    exp = Experiment(name="bracket", kind="solid", domain=MeshDomain("bracket.msh"), law="neo-hookean", E=70.0,
                     nu=0.3, units={"length": "mm", "stress": "GPa", "force": "kN"})
    write_bundle(bundle, Bundle(exp, Observations(np.arange(1, len(X) + 1), X, roles, U)))
    summary = simulate(bundle, tmp_path / "out", quiet=True)
    assert summary["frames"] == 1 and summary["cells"] == mesh.n_cells and np.isfinite(summary["guide_error"])
    rows = np.genfromtxt(tmp_path / "out" / "displacements.csv", delimiter=",", names=True)
    uz = rows["uz"]
    n0, n1 = len(nodes["fixed"]), len(nodes["fixed"]) + len(nodes["load"])
    assert np.abs(uz[:n0]).max() < 1e-6 * abs(dz) and np.allclose(uz[n0:n1], dz, rtol=1e-6)
    # a cantilever: the arm's top goes down, more so farther from the leg
    order = np.argsort(top[:, 0])
    assert (uz[n1:] < 0).all() and (uz[n1:] > dz).all()
    assert np.corrcoef(top[order, 0], uz[n1:][order])[0, 1] < -0.9


PLATE_GEO = """\
SetFactory("OpenCASCADE");
Rectangle(1) = {0, 0, 0, 50, 20};
Disk(2) = {25, 10, 0, 5};
BooleanDifference(3) = { Surface{1}; Delete; }{ Surface{2}; Delete; };
left() = Curve In BoundingBox{-0.1, -0.1, -0.1, 0.1, 20.1, 0.1};
right() = Curve In BoundingBox{49.9, -0.1, -0.1, 50.1, 20.1, 0.1};
Physical Curve("clamp") = {left()};
Physical Curve("grip") = {right()};
Physical Surface("plate") = {3};
"""


def test_planar_geo_meshes_into_tri6_with_its_groups(tmp_path, capsys):
    geo = tmp_path / "plate.geo"
    geo.write_text(PLATE_GEO)
    assert main(["mesh", str(geo), "--size", "2.5", "--out", str(tmp_path / "plate.msh"), "--name", "grip=pull"]) == 0
    assert "tri6" in capsys.readouterr().out
    mesh = jf.read_mesh(tmp_path / "plate.msh")
    assert mesh.element == "tri6" and mesh.dim == 2 and set(mesh.region_names.values()) == {"plate"}
    area = sum(abs(np.linalg.det(np.c_[mesh.nodes[c[1:3]] - mesh.nodes[c[0]]])) / 2 for c in mesh.cells[:, :3])
    assert area == pytest.approx(50 * 20 - np.pi * 25, rel=0.01)  # corner triangles: the hole's chords
    nodes = mesh_faces(tmp_path / "plate.msh")
    assert np.allclose(nodes["clamp"][:, 0], 0) and np.allclose(nodes["pull"][:, 0], 50) and "grip" not in nodes
    hole = [n for n in nodes if n.startswith("edge_")]  # the geometry's unnamed curves, by tag
    r = np.hypot(*(np.vstack([nodes[n] for n in hole])[:, :2] - [25, 10]).T)
    assert hole and (np.isclose(r, 5, atol=1e-9) | (r > 9)).all()


def test_stl_surface_is_meshed_inside(bracket, tmp_path):
    gmsh.initialize(readConfigFiles=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.open(str(bracket))
        gmsh.option.setNumber("Mesh.MeshSizeMax", 3.0)
        gmsh.model.mesh.generate(2)
        gmsh.write(str(tmp_path / "bracket.stl"))
    finally:
        gmsh.finalize()
    r = mesh_geometry(tmp_path / "bracket.stl", 4.0, tmp_path / "stl.msh")
    assert r.element == "tet10" and jf.read_mesh(tmp_path / "stl.msh").n_cells == r.n_cells
    assert sum(f["area"] for f in r.faces.values()) == pytest.approx(AREA, rel=0.02)


def test_errors_name_the_problem(bracket, tmp_path, monkeypatch):
    with pytest.raises(MeshingError, match="no boundary group 'face_99'.*face_1"):
        mesh_geometry(bracket, 5.0, tmp_path / "m.msh", names={"face_99": "fixed"})
    with pytest.raises(MeshingError, match=r"\.msh"):
        mesh_geometry(bracket, 5.0, tmp_path / "m.vtu")
    (tmp_path / "part.obj").write_text("v 0 0 0\n")
    with pytest.raises(MeshingError, match="unknown geometry format '.obj'"):
        mesh_geometry(tmp_path / "part.obj", 5.0, tmp_path / "m.msh")
    tilted = tmp_path / "tilted.geo"
    tilted.write_text("Point(1) = {0, 0, 0}; Point(2) = {10, 0, 5}; Point(3) = {10, 10, 5}; Point(4) = {0, 10, 0};\n"
                      "Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};\n"
                      "Curve Loop(1) = {1, 2, 3, 4}; Plane Surface(1) = {1};\n")
    with pytest.raises(MeshingError, match="one plane z = const"):
        mesh_geometry(tilted, 2.0, tmp_path / "m.msh")
    assert main(["mesh", str(bracket), "--size", "5", "--out", str(tmp_path / "m.msh"), "--name", "face_1"]) == 2
    monkeypatch.setitem(sys.modules, "gmsh", None)  # as if not installed
    with pytest.raises(MeshingError, match=r"nonrigid\[mesh\]"):
        mesh_geometry(bracket, 5.0, tmp_path / "m.msh")
