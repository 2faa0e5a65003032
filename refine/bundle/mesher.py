"""A bundle's mesh from a geometry file: STEP, IGES, STL or a gmsh ``.geo`` meshed by gmsh.

:func:`mesh_geometry` meshes a solid (any volume in the file) into quadratic tetrahedra (``tet10``),
or a planar geometry (surfaces only, in a plane z = const) into quadratic triangles (``tri6``), and
writes the mesh with its boundary facets (``triangle6`` of a solid, ``line3`` of a planar domain)
in named groups: gmsh physical groups of the facets' dimension (a ``.geo``'s ``Physical Surface
("fixed")``) keep their names; a geometry without such groups (a STEP or IGES file, an STL) gets one
group per face, ``face_1``, ``face_2``, ... (a planar domain's boundary curves ``edge_1``, ...: the
gmsh entity tags; so does a face in none of the geometry's groups), which ``names`` renames (``{"face_3": "fixed"}``; several faces may share a
name). The body is the physical group(s) of the top dimension (a ``.geo``'s physical volumes become
the mesh's regions), else one group ``body``. The file is gmsh 2.2 ASCII ``.msh`` (names as
``field_data``, tags as ``gmsh:physical``; VTU would lose the names); :func:`jaxfem.read_mesh` and a bundle's ``domain = { mesh = "FILE" }`` read
it (the named facet groups become the model mesh's ``Mesh.faces``; :func:`mesh_faces` gives their nodes).

gmsh is the extra ``nonrigid[mesh]``; it is imported only here, when a geometry is meshed.
"""

from __future__ import annotations

import re
import tempfile
from dataclasses import dataclass
from pathlib import Path

import meshio
import numpy as np

from refine.exceptions import RefineError

#: geometry file suffixes and how gmsh reads them
FORMATS = {".step": "STEP", ".stp": "STEP", ".iges": "IGES", ".igs": "IGES", ".stl": "STL", ".geo": "gmsh .geo",
           ".brep": "OpenCASCADE BRep"}
_CELLS = {3: ("tetra10", "triangle6", "tet10", "face"), 2: ("triangle6", "line3", "tri6", "edge")}
_PLANAR_TOL = 1e-9  # z extent of a planar geometry, relative to its size


class MeshingError(RefineError, ValueError):
    """A geometry cannot be meshed as asked: an unknown format, no surface or volume in it, a
    surface that is not planar without a volume, an unknown face in ``names``, gmsh missing."""


@dataclass(frozen=True)
class MeshedGeometry:
    """What :func:`mesh_geometry` wrote.

    Attributes:
        path: the mesh file.
        element: ``"tet10"`` (a solid) or ``"tri6"`` (a planar domain).
        n_nodes, n_cells: the mesh's nodes and cells of ``element``.
        faces: per named boundary group, ``{"facets": k, "area": a, "centroid": [x, y, z]}`` (a
            planar domain's edges: their length as ``area``); length unit of the geometry.
        regions: the names of the body's groups (``["body"]`` unless the geometry named them).
    """

    path: Path
    element: str
    n_nodes: int
    n_cells: int
    faces: dict
    regions: list


def mesh_geometry(geometry, size: float, out, names: dict | None = None) -> MeshedGeometry:
    """Mesh ``geometry`` with quadratic elements of edge length about ``size`` and write it to ``out``.

    Args:
        geometry: a STEP (``.step``/``.stp``), IGES (``.iges``/``.igs``), STL, BRep or gmsh ``.geo``
            file. A file with a volume gives a ``tet10`` solid; one with surfaces only, all in one
            plane z = const, a ``tri6`` planar domain. An STL is a closed triangulated surface: its
            faces are found by gmsh's classification (angle 40 degrees) and the volume inside meshed.
        size: the element size everywhere, in the geometry's length unit (a ``.geo``'s own point
            sizes are overridden), > 0.
        out: the mesh file to write, ``.msh`` (gmsh 2.2 ASCII: the meshio format that keeps the names).
        names: new names of boundary groups, ``{"face_3": "fixed", "face_4": "fixed"}``.

    Returns:
        A :class:`MeshedGeometry` (what was written, the faces' facets, areas and centroids).

    Raises:
        MeshingError: gmsh is not installed, the file is missing or of an unknown format, it holds
            no surface, a surface-only geometry is not planar, a name in ``names`` is not a group.
    """
    path = Path(geometry)
    if not path.is_file():
        raise MeshingError(f"{path}: no such geometry file")
    if path.suffix.lower() not in FORMATS:
        raise MeshingError(f"{path}: unknown geometry format {path.suffix!r}; give one of "
                           f"{', '.join(sorted(FORMATS))} ({', '.join(sorted(set(FORMATS.values())))})")
    if not (isinstance(size, (int, float)) and np.isfinite(size) and size > 0):
        raise MeshingError(f"the element size must be a positive number, got {size!r}")
    out = Path(out)
    if out.suffix.lower() != ".msh":
        raise MeshingError(f"{out}: write the mesh as .msh (gmsh 2.2), the mesh format that keeps the faces' names")
    gmsh = _gmsh()
    gmsh.initialize(readConfigFiles=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("General.AbortOnError", 0)
        with tempfile.TemporaryDirectory() as tmp:
            dim = _load(gmsh, path)
            _group(gmsh, dim)
            for key, value in (("Mesh.MeshSizeMin", 0.0), ("Mesh.MeshSizeMax", float(size)),
                               ("Mesh.MeshSizeFromPoints", 0), ("Mesh.MeshSizeFromCurvature", 0),
                               ("Mesh.MeshSizeExtendFromBoundary", 0), ("Mesh.ElementOrder", 2),
                               ("Mesh.HighOrderOptimize", 2), ("Mesh.MshFileVersion", 4.1), ("Mesh.Binary", 0),
                               # an STL's faces are triangulations: midside nodes on them bend nothing real
                               ("Mesh.SecondOrderLinear", int(path.suffix.lower() == ".stl"))):
                gmsh.option.setNumber(key, value)
            try:
                gmsh.model.mesh.generate(dim)
            except Exception as e:  # gmsh raises a bare Exception with its log's last error
                raise MeshingError(f"{path}: gmsh could not mesh the geometry at size {size:g}: {e}") from None
            _check_jacobians(gmsh, dim, path, size)
            raw = Path(tmp) / "mesh.msh"
            gmsh.write(str(raw))
            m = meshio.read(raw)
    finally:
        gmsh.finalize()
    mesh, faces, regions = _named(m, dim, names or {}, path)
    out.parent.mkdir(parents=True, exist_ok=True)
    meshio.write(out, mesh, file_format="gmsh22", binary=False)
    cell, _, element, _ = _CELLS[dim]
    return MeshedGeometry(out, element, len(mesh.points), len(mesh.cells[0].data), faces, regions)


def mesh_faces(path) -> dict[str, np.ndarray]:
    """The nodes of each named boundary group of a mesh written by :func:`mesh_geometry`:
    ``{name: (k, 3) coordinates}`` (every node of its facets, midside nodes included), e.g. to
    place a bundle's boundary points on the face ``fixed``."""
    m = meshio.read(path)
    tags = m.cell_data.get("gmsh:physical")
    if tags is None:
        raise MeshingError(f"{path}: no named groups (cell data gmsh:physical) in the mesh")
    facet_dims = {b.type: d for b, d in ((b, {"triangle6": 2, "line3": 1}.get(b.type)) for b in m.cells) if d}
    out = {}
    for name, (tag, dim) in ((n, np.ravel(v)[:2]) for n, v in m.field_data.items()):
        nodes = [b.data[np.asarray(t) == tag].ravel() for b, t in zip(m.cells, tags)
                 if facet_dims.get(b.type) == dim]
        if nodes and sum(len(n) for n in nodes):
            out[name] = m.points[np.unique(np.concatenate(nodes))]
    return out


def _gmsh():
    try:
        import gmsh
    except ImportError:
        raise MeshingError("meshing a geometry needs gmsh: pip install 'nonrigid[mesh]' (or pip install gmsh)") from None
    return gmsh


def _load(gmsh, path: Path) -> int:
    """Open the geometry; its dimension to mesh (3 with a volume, 2 for a planar domain)."""
    try:
        if path.suffix.lower() == ".stl":
            gmsh.merge(str(path))
            gmsh.model.mesh.classifySurfaces(np.deg2rad(40.0), True, True, np.pi)
            gmsh.model.mesh.createGeometry()
            surfaces = [t for _, t in gmsh.model.getEntities(2)]
            gmsh.model.geo.addVolume([gmsh.model.geo.addSurfaceLoop(surfaces)])
            gmsh.model.geo.synchronize()
        else:
            gmsh.open(str(path))
    except Exception as e:
        raise MeshingError(f"{path}: gmsh could not read it as {FORMATS[path.suffix.lower()]}: {e}") from None
    if gmsh.model.getEntities(3):
        return 3
    if not gmsh.model.getEntities(2):
        raise MeshingError(f"{path}: the geometry holds no surface or volume to mesh")
    return 2


def _check_jacobians(gmsh, dim: int, path: Path, size: float) -> None:
    """Raise where a quadratic cell's Jacobian is not positive everywhere (gmsh's scaled Jacobian)."""
    _, tags, _ = gmsh.model.mesh.getElements(dim)
    tags = np.concatenate([np.asarray(t) for t in tags]) if tags else np.empty(0)
    q = np.asarray(gmsh.model.mesh.getElementQualities(tags, "minSJ")) if len(tags) else np.empty(0)
    if (q <= 0).any():
        raise MeshingError(f"{path}: {int((q <= 0).sum())} of {len(q)} quadratic cells at size {size:g} are inverted "
                           "(their midside nodes on a curved face fold them); mesh with a smaller --size")


def _group(gmsh, dim: int) -> None:
    """Physical groups to keep: the body (top dimension) and the boundary (one below), each entity
    of the boundary in a group (its own ``face_TAG``/``edge_TAG`` where the geometry put it in none)."""
    groups = gmsh.model.getPhysicalGroups()
    if not any(d == dim for d, _ in groups):
        tag = gmsh.model.addPhysicalGroup(dim, [t for _, t in gmsh.model.getEntities(dim)])
        gmsh.model.setPhysicalName(dim, tag, "body")
    named = {t for d, g in groups if d == dim - 1 for t in gmsh.model.getEntitiesForPhysicalGroup(d, g)}
    word = _CELLS[dim][3]
    for _, t in gmsh.model.getEntities(dim - 1):
        if t not in named:  # in no group of the geometry's: its own, by its tag
            g = gmsh.model.addPhysicalGroup(dim - 1, [t])
            gmsh.model.setPhysicalName(dim - 1, g, f"{word}_{t}")
    for d, g in gmsh.model.getPhysicalGroups():
        if not gmsh.model.getPhysicalName(d, g):
            gmsh.model.setPhysicalName(d, g, f"{word if d == dim - 1 else 'region'}_{g}")


def _named(m: meshio.Mesh, dim: int, names: dict, path: Path):
    """The written mesh: the body's cells and the boundary facets with gmsh:physical tags, renamed
    by ``names``, cells oriented positively; with the faces' summary and the regions' names."""
    cell, facet, _, word = _CELLS[dim]
    groups = {n: (int(np.ravel(v)[0]), int(np.ravel(v)[1])) for n, v in m.field_data.items()}
    facet_groups = {n: t for n, (t, d) in groups.items() if d == dim - 1}
    unknown = sorted(set(names) - set(facet_groups))
    if unknown:
        raise MeshingError(f"{path}: no boundary group {', '.join(map(repr, unknown))} to rename; the geometry's "
                           f"{word}s are {', '.join(sorted(facet_groups, key=_natural))}")
    tags = m.cell_data["gmsh:physical"]
    blocks = {}
    for b, t in zip(m.cells, tags):
        if b.type in (cell, facet):
            data, t0 = blocks.get(b.type, (np.empty((0, b.data.shape[1]), np.int64), np.empty(0, np.int64)))
            blocks[b.type] = (np.vstack([data, b.data]), np.concatenate([t0, np.asarray(t, np.int64)]))
    if cell not in blocks:
        raise MeshingError(f"{path}: gmsh made no {cell} cells of the geometry")
    new = {}  # final name -> tag; facets renamed to one name share the first one's tag
    remap = {}
    for n, t in sorted(facet_groups.items(), key=lambda kv: kv[1]):
        final = names.get(n, n)
        remap[t] = new.setdefault(final, t)
    cells, ctags = blocks[cell]
    used = np.unique(np.concatenate([cells.ravel(), blocks.get(facet, (np.empty((0, 1), np.int64),))[0].ravel()]))
    index = np.full(len(m.points), -1, np.int64)
    index[used] = np.arange(len(used))
    points = np.asarray(m.points, np.float64)[used]
    extent = np.ptp(points, axis=0)
    if dim == 2 and extent[2] > _PLANAR_TOL * max(extent.max(), 1.0):
        raise MeshingError(f"{path}: surfaces without a volume must lie in one plane z = const (a planar domain), "
                           f"but they span {extent[2]:.3g} in z; give a closed solid (a volume) for a 3D mesh")
    out_cells = [(cell, _oriented(points, index[cells], dim))]
    data = [ctags]
    faces = {}
    if facet in blocks:
        f, ftags = blocks[facet]
        ftags = np.array([remap.get(int(t), int(t)) for t in ftags], np.int64)
        out_cells.append((facet, index[f]))
        data.append(ftags)
        for n, t in new.items():
            faces[n] = _measure(points, index[f][ftags == t], dim)
    field = {n: np.array([t, d]) for n, (t, d) in groups.items() if d == dim}
    field.update({n: np.array([t, dim - 1]) for n, t in new.items()})
    regions = sorted(n for n, (t, d) in groups.items() if d == dim)
    cell_data = {"gmsh:physical": data, "gmsh:geometrical": [d.copy() for d in data]}
    return meshio.Mesh(points, out_cells, cell_data=cell_data, field_data=field), faces, regions


def _oriented(points, cells, dim):
    """Cells with a positive volume (area, seen from +z): a negative one's nodes 1 and 2 swapped."""
    x = points[cells[:, : dim + 1]]
    e = x[:, 1:, :dim] - x[:, :1, :dim]
    flip = np.linalg.det(e) < 0
    perm = [0, 2, 1, 3, 6, 5, 4, 7, 9, 8] if dim == 3 else [0, 2, 1, 5, 4, 3]
    cells = cells.copy()
    cells[flip] = cells[flip][:, perm]
    return cells


def _measure(points, facets, dim) -> dict:
    """A group's facet count, area (a 2D edge: length) and area-weighted centroid, from the corners."""
    if dim == 3:
        a, b, c = (points[facets[:, k]] for k in range(3))
        w = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
        mid = (a + b + c) / 3
    else:
        a, b = points[facets[:, 0]], points[facets[:, 1]]
        w, mid = np.linalg.norm(b - a, axis=1), (a + b) / 2
    total = float(w.sum())
    centroid = (w @ mid / total).tolist() if total > 0 else mid.mean(axis=0).tolist()
    return {"facets": int(len(facets)), "area": total, "centroid": [float(c) for c in centroid]}


def _natural(name: str):
    return [int(s) if s.isdigit() else s for s in re.split(r"(\d+)", name)]
