"""``nonrigid mesh GEOMETRY --size H --out MESH``: a bundle's mesh from a STEP, IGES, STL or .geo file."""

from __future__ import annotations

import argparse
from pathlib import Path

EPILOG = """\
A geometry with a volume gives quadratic tetrahedra (tet10); one of surfaces only, in a plane
z = const (e.g. a .geo's Plane Surface), quadratic triangles (tri6). The boundary's facets are
written in named groups: the geometry's physical groups keep their names (a .geo's
Physical Surface("fixed") = {3};); faces without one are face_1, face_2, ... (a planar domain's
curves edge_1, ...) by gmsh's entity tag, and --name renames them. The summary lists every
face's area and centroid, to tell which is which. The mesh is gmsh 2.2 .msh, which a solid
bundle reads as domain = { mesh = "MESH" } (docs/mesh.md).

examples:
  nonrigid mesh bracket.step --size 4 --out bundle/bracket.msh --name face_1=fixed --name face_6=load
  nonrigid mesh plate.geo --size 2 --out plate.msh
"""


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``mesh`` sub-command to ``subparsers`` (from ``ArgumentParser.add_subparsers``)."""
    p = subparsers.add_parser("mesh", help="mesh a STEP / IGES / STL / .geo geometry with gmsh (extra: nonrigid[mesh])",
                              description="Mesh a geometry into tet10 (a solid) or tri6 (a planar domain) with named "
                              "faces, for a bundle's domain = { mesh = ... }.", epilog=EPILOG,
                              formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("geometry", help="a .step/.stp, .iges/.igs, .stl, .brep or gmsh .geo file")
    p.add_argument("--size", type=float, required=True, metavar="H",
                   help="element size everywhere, in the geometry's length unit")
    p.add_argument("--out", required=True, metavar="MESH", help="the mesh file to write (.msh)")
    p.add_argument("--name", action="append", default=[], metavar="FACE=NAME",
                   help="rename a boundary group, e.g. face_3=fixed (repeat; faces may share a name)")
    p.set_defaults(run=run)
    return p


def run(args: argparse.Namespace) -> int:
    """Carry out ``nonrigid mesh`` (``args`` from the parser of :func:`add_parser`); 0 on success."""
    mesh(args.geometry, args.size, args.out, names=parse_names(args.name))
    return 0


def parse_names(items) -> dict:
    """``["face_3=fixed", ...]`` as ``{"face_3": "fixed"}``.

    Raises:
        refine.bundle.mesher.MeshingError: an item is not ``FACE=NAME`` or renames a face twice.
    """
    from refine.bundle.mesher import MeshingError

    names = {}
    for item in items:
        old, sep, new = (s.strip() for s in item.partition("="))
        if not sep or not old or not new:
            raise MeshingError(f"--name {item!r}: give FACE=NAME, e.g. --name face_3=fixed")
        if old in names and names[old] != new:
            raise MeshingError(f"--name: {old!r} is renamed twice ({names[old]!r} and {new!r})")
        names[old] = new
    return names


def mesh(geometry, size: float, out, names: dict | None = None, quiet: bool = False):
    """Mesh ``geometry`` at element size ``size`` into ``out`` with named faces
    (:func:`refine.bundle.mesher.mesh_geometry`: formats, naming and errors) and print a summary:
    the element, counts and each face's facets, area and centroid.

    Returns:
        The :class:`refine.bundle.mesher.MeshedGeometry`.
    """
    from refine.bundle.mesher import mesh_geometry

    result = mesh_geometry(geometry, size, out, names=names)
    if not quiet:
        print(f"meshed {Path(geometry).name} at size {size:g}: {result.n_cells} {result.element} cells, "
              f"{result.n_nodes} nodes; body: {', '.join(result.regions)}")
        what = "area" if result.element == "tet10" else "length"
        for name, f in result.faces.items():
            c = ", ".join(f"{v:.4g}" for v in f["centroid"][: 3 if result.element == "tet10" else 2])
            print(f"  {name:<12} {f['facets']:>6} facets  {what} {f['area']:.4g}  centroid ({c})")
        print(f"  wrote {out}")
    return result
