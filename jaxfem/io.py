"""Meshes and results in and out through meshio: read any mesh meshio reads, write VTU for ParaView.

:func:`read_mesh` keeps the highest-dimensional cells of a file, carries region tags such as
``gmsh:physical`` into ``Mesh.regions`` with their names, keeps the file's named groups of boundary
facets (a gmsh file's physical surfaces of a tet mesh, physical curves of a triangle mesh) as
``Mesh.faces``, and drops nodes no cell uses (with a warning). :func:`write_vtu` writes a mesh with nodal and
cell results, 2D vectors and tensors padded to 3D so that ParaView can warp and display them;
:func:`write_points_vtu` writes a point cloud (e.g. measured points) and :func:`write_pvd` a time
series of VTU files that ParaView opens as one animated dataset.
"""

from __future__ import annotations

import warnings
from os import PathLike
from pathlib import Path
from xml.sax.saxutils import quoteattr

import meshio
import numpy as np

from .elements import FROM_MESHIO, get_element
from .exceptions import MeshError
from .mesh import Mesh, check_orientation, fix_orientation

#: cell-data keys read as region tags, first found wins
REGION_KEYS = ("region", "gmsh:physical", "medit:ref", "CellEntityIds", "cell_tags")


def read_mesh(source: str | PathLike | meshio.Mesh, element: str | None = None,
              region_key: str | None = None) -> Mesh:
    """Read a mesh from a file (any format meshio reads) or a ``meshio.Mesh``.

    Args:
        source: a path, or a ``meshio.Mesh``.
        element: our element name (``"tri6"``...) of the cells to keep; by default the cells of the
            highest dimension, which must then all be of one type.
        region_key: the cell-data array holding region tags; by default the first of
            :data:`REGION_KEYS` present. Tags are kept as they are (a gmsh physical tag of 1 stays 1);
            gmsh-style ``field_data`` ``{name: [tag, dim]}`` of the cells' dimension names them.

    Returns:
        A :class:`Mesh` with ``dim``-component nodes (a 2D mesh's z = const is dropped); ``tri3``
        and ``tet4`` cells are reordered counter-clockwise where needed. Cells one dimension lower
        of the cells' facet type (``triangle6`` of ``tet10``, ``line`` of ``tri3``...) tagged by the
        region key with a name of that dimension in ``field_data`` become ``Mesh.faces[name]``: the
        mesh's boundary facets they cover, in the mesh's own node order (a group's facets inside the
        body are dropped with a warning; a group with none on the boundary is left out).

    Raises:
        MeshError: no cells of a supported type, mixed types without ``element``, a 2D mesh that is
            not flat, or an unknown ``region_key``.
        InvertedElementError: a cell of another type has a non-positive Jacobian.
    """
    m = source if isinstance(source, meshio.Mesh) else meshio.read(source)
    dims = {i: get_element(FROM_MESHIO[b.type]).dim for i, b in enumerate(m.cells)
            if b.type in FROM_MESHIO}  # block index -> dimension of its cells
    kinds = {FROM_MESHIO[m.cells[i].type] for i, d in dims.items() if d >= 2 and d == max(dims.values())}
    if element is None and len(kinds) > 1:
        raise MeshError(f"the mesh mixes {', '.join(sorted(kinds))} cells; choose one with element=...")
    name = get_element(element).name if element is not None else next(iter(kinds), None)
    blocks = [i for i in dims if FROM_MESHIO[m.cells[i].type] == name]
    if not blocks:
        found = sorted({b.type for b in m.cells})
        raise MeshError(f"no {element or 'supported'} cells in the mesh (meshio types found: {found}); "
                        f"supported: {sorted(FROM_MESHIO)}")
    el = get_element(name)
    cells = np.concatenate([m.cells[i].data for i in blocks]).astype(np.int64)
    regions, region_names = _regions(m, blocks, el.dim, region_key)

    points = np.asarray(m.points, dtype=np.float64)
    if points.shape[1] > el.dim:
        extra = points[:, el.dim:]
        if np.ptp(extra, axis=0).max() > 1e-12 * max(np.ptp(points, axis=0).max(), 1.0):
            raise MeshError(f"{name} cells need a flat mesh in the x-y plane, but the z coordinates vary "
                            f"by {np.ptp(extra, axis=0).max():.3g}; surface meshes in 3D are not supported")
        points = points[:, : el.dim]
    used = np.zeros(len(points), bool)
    used[cells] = True
    if not used.all():
        warnings.warn(f"read_mesh: dropped {int((~used).sum())} of {len(points)} nodes that no {name} cell "
                      "uses (e.g. nodes of lower-dimensional cells or stray points); nodes are renumbered",
                      stacklevel=2)
        points, cells = points[used], (np.cumsum(used) - 1)[cells]
    mesh = Mesh(points, cells, name, regions, region_names)
    if name in ("tri3", "tet4"):
        mesh = fix_orientation(mesh)
    else:
        check_orientation(mesh)
    groups = _facet_groups(m, el, region_key)
    if groups and not used.all():
        groups = {n: (np.cumsum(used) - 1)[f] if used[f].all() else None for n, f in groups.items()}
    return mesh.with_faces(_on_boundary(mesh, groups)) if groups else mesh


def _facet_groups(m: meshio.Mesh, el, key) -> dict[str, np.ndarray]:
    """``{name: (k, corners) node indices}``: the file's named facet groups (cells of ``el``'s facet
    type tagged by the region key, names from gmsh-style ``field_data`` of dimension ``el.dim - 1``)."""
    facet = get_element(el.facet) if el.facet else None
    key = key or next((k for k in REGION_KEYS if k in m.cell_data), None)
    if facet is None or key is None or key not in m.cell_data:
        return {}
    names = {int(np.ravel(v)[0]): n for n, v in m.field_data.items()
             if np.size(v) == 2 and int(np.ravel(v)[1]) == el.dim - 1}
    out: dict[str, list] = {}
    for block, tags in zip(m.cells, m.cell_data[key]):
        if block.type != facet.meshio:
            continue
        tags = np.asarray(tags).reshape(len(block.data), -1)[:, 0].astype(np.int64)
        for tag, name in names.items():
            out.setdefault(name, []).append(np.asarray(block.data)[tags == tag, : facet.corners])
    return {n: np.concatenate(f).astype(np.int64) for n, f in out.items() if sum(len(a) for a in f)}


def _on_boundary(mesh: Mesh, groups: dict) -> dict[str, np.ndarray]:
    """Each group's facets as the mesh's boundary facets with the same corners (see :func:`read_mesh`)."""
    faces = {}
    for name, f in groups.items():
        if f is None:
            warnings.warn(f"read_mesh: face {name!r} uses nodes no {mesh.element} cell uses; it is left out",
                          stacklevel=3)
            continue
        facets, missed = mesh.facets_with_corners(f)
        if missed:
            warnings.warn(f"read_mesh: {missed} of {len(f)} facets of face {name!r} are not on the mesh's boundary "
                          "(an interface inside the body?); they are left out", stacklevel=3)
        if len(facets):
            faces[name] = facets
    return faces


def _regions(m: meshio.Mesh, blocks, dim, key):
    """Region tags ``(n_cells,)`` of the chosen blocks and their names ``{tag: name}``."""
    if key is None:
        key = next((k for k in REGION_KEYS if k in m.cell_data), None)
        if key is None:
            return None, {}
    elif key not in m.cell_data:
        raise MeshError(f"no cell data {key!r} in the mesh; it has {sorted(m.cell_data)}")
    tags = np.concatenate([np.asarray(m.cell_data[key][i]).reshape(len(m.cells[i].data), -1)[:, 0]
                           for i in blocks])
    if not np.allclose(tags, np.round(tags)):
        raise MeshError(f"cell data {key!r} is not integer-valued, so it cannot be region tags")
    tags = np.round(tags).astype(np.int64)
    names = {int(v[0]): n for n, v in m.field_data.items()  # gmsh style: name -> [tag, dim]
             if np.size(v) == 2 and int(np.ravel(v)[1]) == dim and int(np.ravel(v)[0]) in tags}
    return tags, names


def to_meshio(mesh: Mesh, point_data: dict | None = None, cell_data: dict | None = None) -> meshio.Mesh:
    """The mesh as a ``meshio.Mesh`` with 3D points, its region tags as cell data ``"region"``, their
    names as gmsh-style ``field_data`` ``{name: [tag, dim]}``, and the data converted as in
    :func:`write_vtu`."""
    points = np.zeros((mesh.n_nodes, 3))
    points[:, : mesh.dim] = mesh.nodes
    pd = {k: _for_vtk(v, mesh.n_nodes, mesh.dim, f"point_data[{k!r}]") for k, v in (point_data or {}).items()}
    cd = {"region": [mesh.regions]}
    for k, v in (cell_data or {}).items():
        cd[k] = [_for_vtk(v, mesh.n_cells, mesh.dim, f"cell_data[{k!r}]")]
    names = {n: np.array([tag, mesh.dim]) for tag, n in mesh.region_names.items()}  # gmsh style
    return meshio.Mesh(points, [(mesh.el.meshio, mesh.cells)], point_data=pd, cell_data=cd, field_data=names)


def write_vtu(path: str | PathLike, mesh: Mesh, point_data: dict | None = None,
              cell_data: dict | None = None) -> None:
    """Write the mesh and results to a VTU file for ParaView.

    Args:
        path: the file to write (``.vtu``).
        mesh: the mesh; its region tags are written as cell data ``"region"``.
        point_data: nodal arrays ``(n_nodes,)``, ``(n_nodes, k)`` or ``(n_nodes, dim, dim)``, e.g.
            ``{"displacement": u}`` in length units.
        cell_data: per-cell arrays ``(n_cells, ...)``, e.g. strains or stresses (Pa) averaged over
            the quadrature points (``s.mean(axis=1)``).

    2D vectors ``(n, 2)`` are padded with a zero z component and 2D tensors ``(n, 2, 2)`` to
    ``(n, 3, 3)`` (``zz`` = 0: add the plane-stress or plane-strain value yourself if you need it),
    written as 9 components in row-major order; other shapes are written flattened per row.
    """
    to_meshio(mesh, point_data, cell_data).write(path, file_format="vtu")


def _for_vtk(a, n, dim, what):
    a = np.asarray(a)
    if a.shape[:1] != (n,):
        raise MeshError(f"{what} must have {n} rows, one per {'node' if 'point' in what else 'cell'}, "
                        f"got shape {a.shape}")
    if a.dtype == bool:
        a = a.astype(np.int32)
    if dim == 2 and a.shape[1:] == (2,):
        a = np.concatenate([a, np.zeros((n, 1), a.dtype)], axis=1)
    elif a.shape[1:] == (dim, dim):
        a = np.pad(a, ((0, 0), (0, 3 - dim), (0, 3 - dim)))
    return np.ascontiguousarray(a.reshape(n, -1) if a.ndim > 2 else a)


def write_points_vtu(path: str | PathLike, points, point_data: dict | None = None) -> None:
    """Write a point cloud (one VTK vertex per point) with per-point data to a VTU file.

    Args:
        path: the file to write (``.vtu``).
        points: ``(n, 2)`` or ``(n, 3)`` coordinates (length unit); 2D points get z = 0.
        point_data: per-point arrays ``(n,)``, ``(n, k)`` or ``(n, dim, dim)``, padded as in
            :func:`write_vtu` (NaN, e.g. a point lost in a frame, is written as NaN).
    """
    points = np.asarray(points, dtype=np.float64)
    n, dim = points.shape
    xyz = np.zeros((n, 3))
    xyz[:, :dim] = points
    pd = {k: _for_vtk(v, n, dim, f"point_data[{k!r}]") for k, v in (point_data or {}).items()}
    meshio.Mesh(xyz, [("vertex", np.arange(n).reshape(-1, 1))], point_data=pd).write(path, file_format="vtu")


def write_pvd(path: str | PathLike, files, times=None) -> Path:
    """Write a ParaView collection (``.pvd``) that lists VTU files as the steps of a time series.

    Args:
        path: the ``.pvd`` file to write.
        files: the VTU files, one per step, in order; written into the collection relative to the
            ``.pvd`` file's folder (keep them together when moving the results).
        times: the time value of each step (e.g. frame numbers); default ``0, 1, 2, ...``.

    Returns:
        The path written. Open it in ParaView (File > Open) to step through the files.
    """
    path = Path(path)
    files = [Path(f) for f in files]
    times = list(range(len(files))) if times is None else list(times)
    if len(times) != len(files):
        raise MeshError(f"write_pvd: {len(files)} files but {len(times)} times; give one time per file")
    rows = []
    for t, f in zip(times, files):
        try:
            name = f.resolve().relative_to(path.parent.resolve()).as_posix()
        except ValueError:  # not under the collection's folder: keep the absolute path
            name = f.resolve().as_posix()
        rows.append(f'    <DataSet timestep="{float(t)!r}" group="" part="0" file={quoteattr(name)}/>')
    path.write_text('<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">\n'
                    "  <Collection>\n" + "\n".join(rows) + "\n  </Collection>\n</VTKFile>\n")
    return path


def read_pvd(path: str | PathLike) -> list[tuple[float, Path]]:
    """The steps of a ParaView collection written by :func:`write_pvd`: ``[(time, vtu path), ...]``."""
    import xml.etree.ElementTree as ET

    path = Path(path)
    root = ET.parse(path).getroot()
    return [(float(d.get("timestep", 0.0)), path.parent / d.get("file")) for d in root.iter("DataSet")]
