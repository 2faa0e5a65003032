"""Reading meshes through meshio and writing VTU results."""

import meshio
import numpy as np
import pytest

from jaxfem.exceptions import MeshError
from jaxfem.io import read_mesh, to_meshio, write_vtu
from jaxfem.mesh import box, rectangle
from jaxfem.mesher import plate
from jaxfem.shapes import Ellipse

MESHES = {
    "tri3": lambda: rectangle(0, 0, 2, 1, 4, 2, "tri3"),
    "tri6": lambda: plate(0, 0, 10, 6, 1.5, inclusions=[Ellipse(5, 3, 2, 1, 0.3)], element="tri6"),
    "quad4": lambda: rectangle(0, 0, 2, 1, 4, 2, "quad4"),
    "tet4": lambda: box(0, 0, 0, 1, 1, 1, 2, 2, 2, "tet4"),
    "tet10": lambda: box(0, 0, 0, 1, 1, 1, 2, 2, 2, "tet10"),
    "hex8": lambda: box(0, 0, 0, 1, 1, 1, 2, 2, 2, "hex8"),
}


@pytest.mark.parametrize("element", sorted(MESHES))
def test_write_vtu_then_read_mesh_round_trip(element, tmp_path):
    mesh = MESHES[element]()
    mesh = mesh.with_regions(np.arange(mesh.n_cells) % 3)
    rng = np.random.default_rng(0)
    u = rng.normal(size=(mesh.n_nodes, mesh.dim))
    stress = rng.normal(size=(mesh.n_cells, mesh.dim, mesh.dim))
    path = tmp_path / f"{element}.vtu"
    write_vtu(path, mesh, point_data={"displacement": u},
              cell_data={"stress": stress, "E": np.ones(mesh.n_cells)})

    back = read_mesh(path)
    assert back.element == element
    np.testing.assert_array_equal(back.cells, mesh.cells)
    np.testing.assert_array_equal(back.regions, mesh.regions)
    np.testing.assert_allclose(back.nodes, mesh.nodes, rtol=0, atol=1e-12)

    raw = meshio.read(path)  # what ParaView sees: 3-component vectors, 9-component tensors
    assert raw.point_data["displacement"].shape == (mesh.n_nodes, 3)
    np.testing.assert_allclose(raw.point_data["displacement"][:, : mesh.dim], u)
    s = raw.cell_data["stress"][0].reshape(-1, 3, 3)
    np.testing.assert_allclose(s[:, : mesh.dim, : mesh.dim], stress)
    assert np.all(s[:, mesh.dim:, :] == 0) and np.all(s[:, :, mesh.dim:] == 0)


def test_read_gmsh_file_with_physical_groups(tmp_path):
    mesh = rectangle(0, 0, 2, 1, 4, 2, "tri3")
    tags = np.where(mesh.centroids()[:, 0] < 1, 1, 2)
    cells = mesh.cells.copy()
    cells[::2] = cells[::2][:, [0, 2, 1]]  # half of them clockwise
    points = np.vstack([np.c_[mesh.nodes, np.zeros(mesh.n_nodes)], [[5.0, 5.0, 0.0]]])  # a stray node
    lines = np.array([[0, 1], [1, 2]])
    m = meshio.Mesh(points, [("line", lines), ("triangle", cells[tags == 1]), ("triangle", cells[tags == 2])],
                    cell_data={"gmsh:physical": [np.array([3, 3]), tags[tags == 1], tags[tags == 2]],
                               "gmsh:geometrical": [np.array([1, 1]), tags[tags == 1], tags[tags == 2]]},
                    field_data={"matrix": np.array([1, 2]), "inclusion": np.array([2, 2]),
                                "edge": np.array([3, 1])})
    path = tmp_path / "plate.msh"
    meshio.write(path, m, file_format="gmsh22", binary=False)

    with pytest.warns(UserWarning, match="dropped 1 of 16 nodes"):
        back = read_mesh(path)
    assert back.element == "tri3" and back.n_nodes == 15 and back.n_cells == 16
    assert back.region_names == {1: "matrix", 2: "inclusion"}
    assert np.bincount(back.regions).tolist() == [0, 8, 8]
    assert (back.jacobian_dets() > 0).all()  # clockwise triangles were reordered
    assert back.volumes().sum() == pytest.approx(2.0)


def test_read_mesh_choices_and_errors():
    tri, quad = rectangle(0, 0, 1, 1, 2, 2, "tri3"), rectangle(0, 0, 1, 1, 2, 2, "quad4")
    flat = np.c_[tri.nodes, np.zeros(tri.n_nodes)]
    mixed = meshio.Mesh(flat, [("triangle", tri.cells), ("quad", quad.cells)])
    tets = box(0, 0, 0, 1, 1, 1, 1, 1, 1, "tet4")
    faces = meshio.Mesh(tets.nodes, [("triangle", tets.cells[:, :3]), ("tetra", tets.cells)])
    assert read_mesh(faces).element == "tet4"  # the highest dimension wins
    with pytest.raises(MeshError, match="mixes"):
        read_mesh(mixed)
    assert read_mesh(mixed, element="quad4").n_cells == 4
    assert read_mesh(to_meshio(tri)).regions.tolist() == [0] * tri.n_cells
    tagged = tri.with_regions(np.arange(tri.n_cells) % 2, {1: "soft"})
    assert read_mesh(to_meshio(tagged)).region_names == {1: "soft"}
    with pytest.raises(MeshError, match="no cell data"):
        read_mesh(to_meshio(tri), region_key="material")
    bent = meshio.Mesh(np.c_[tri.nodes, tri.nodes[:, 0] ** 2], [("triangle", tri.cells)])
    with pytest.raises(MeshError, match="flat"):
        read_mesh(bent)
    with pytest.raises(MeshError, match="no supported cells"):
        read_mesh(meshio.Mesh(np.zeros((2, 3)), [("line", np.array([[0, 1]]))]))
    with pytest.raises(MeshError, match="one per node"):
        to_meshio(tri, point_data={"u": np.zeros((3, 2))})
