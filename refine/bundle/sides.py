"""Named sides of a domain's outline (2D) and named faces of a mesh domain (3D or 2D): where a
measured force (forces.csv) crosses the boundary, where grips hold, where boundary points lie.

A force is only meaningful across a well-defined piece of the outline. A rectangle has four
(``left``, ``right``, ``bottom``, ``top``); any 2D domain may name more in experiment.toml:

    domain = { polygon = [...], sides = { grip = [[120.0, 10.0], [120.0, 70.0]] } }

A side is the stretch of the outer outline that runs counter-clockwise (the material on its
left) from the place nearest its first end to the place nearest its second. An end is a
position ``[x, y]`` (length unit) or, for a polygon, the index of one of its vertices (from 0).

A mesh domain names its faces in the mesh file (gmsh physical groups of boundary facets, read by
:func:`jaxfem.read_mesh` as ``Mesh.faces``) or in experiment.toml, by the boundary facets all of
whose nodes lie in a box or on a plane (length unit; ``tol``, the slack of either, defaults to 1e-9 of
the mesh's size):

    domain = { mesh = "body.msh", faces = { fixed = { box = [x0, y0, z0, x1, y1, z1] },
                                            loaded = { plane = [nx, ny, nz, d], tol = 0.01 } } }

(a plane holds the points x with n . x = d, n normalised here; in 2D a box is [x0, y0, x1, y1] and
a plane [nx, ny, d]). A face named in experiment.toml wins over the mesh file's face of that name,
and a named face over the bounding box's side of that name (``left`` ... ``front``).
"""

from __future__ import annotations

import math

import numpy as np

from refine.exceptions import ExperimentError

Side = tuple  # (name, first end, second end); an end is (x, y) or a vertex index

EXAMPLE = 'sides = { NAME = [[x0, y0], [x1, y1]] }'


def _end(value, what: str):
    if isinstance(value, int) and not isinstance(value, bool):
        if value < 0:
            raise ExperimentError(f"{what} is a vertex index and must be >= 0, got {value}")
        return value
    try:
        x, y = (float(c) for c in value)
    except (TypeError, ValueError):
        raise ExperimentError(f"{what} must be a position [x, y] or a polygon vertex index, got {value!r}") from None
    if not (math.isfinite(x) and math.isfinite(y)):
        raise ExperimentError(f"{what} has a NaN or inf coordinate")
    return (x, y)


def sides_from_toml(table) -> tuple[Side, ...]:
    """``domain.sides`` (a table name -> [first end, second end]) as a tuple of (name, a, b)."""
    if not table:
        return ()
    if not isinstance(table, dict):
        raise ExperimentError(f"domain.sides must be a table, e.g. {EXAMPLE}; got {table!r}")
    out = []
    for name, ends in table.items():
        if not isinstance(ends, (list, tuple)) or len(ends) != 2:
            raise ExperimentError(f"domain.sides.{name} must list two ends (from, to counter-clockwise), e.g. "
                                  f"{EXAMPLE}; got {ends!r}")
        out.append((str(name), _end(ends[0], f"domain.sides.{name}[0]"), _end(ends[1], f"domain.sides.{name}[1]")))
    return tuple(out)


def checked_sides(sides, n_vertices: int | None) -> tuple[Side, ...]:
    """``sides`` (pairs or the TOML table) checked: vertex indices only where the domain has
    ``n_vertices`` (a polygon), and below that count."""
    sides = sides_from_toml(sides) if isinstance(sides, dict) else tuple(
        (str(n), _end(a, f"domain.sides.{n}[0]"), _end(b, f"domain.sides.{n}[1]")) for n, a, b in sides)
    for name, *ends in sides:
        for e in ends:
            if isinstance(e, int) and (n_vertices is None or e >= n_vertices):
                raise ExperimentError(f"domain.sides.{name}: vertex index {e} " + (
                    "is only for a polygon domain; give a position [x, y]" if n_vertices is None
                    else f"is out of range (the polygon has {n_vertices} vertices)"))
    return sides


def sides_to_toml(sides) -> dict:
    """The ``sides`` entry of the domain's TOML table (empty when there are none)."""
    return {"sides": {n: [a if isinstance(a, int) else list(a), b if isinstance(b, int) else list(b)]
                      for n, a, b in sides}} if sides else {}


def undefined_side(name: str, known) -> str:
    """The message for a force on a side the domain does not define (no guess is made)."""
    listed = f"the domain's sides are {list(known)}" if known else "the domain names no sides"
    return (f"unknown edge {name!r}: the domain does not define that side ({listed}). Name it in experiment.toml, "
            f"e.g. domain = {{ ..., sides = {{ {name} = [[x0, y0], [x1, y1]] }} }}: the outline counter-clockwise "
            "from the place nearest [x0, y0] to the place nearest [x1, y1] (a polygon may give vertex indices); "
            "left/right/bottom/top are defined for a rectangle only")


Face = tuple  # (name, "box" | "plane", numbers, tol or None)
FACE_EXAMPLE = ("faces = { NAME = { box = [x0, y0, z0, x1, y1, z1] } } or "
                "{ NAME = { plane = [nx, ny, nz, d], tol = t } }")
_FACE_SIZES = {"box": (4, 6), "plane": (3, 4)}


def checked_faces(faces) -> tuple[Face, ...]:
    """``domain.faces`` (the TOML table name -> {box = [...]} | {plane = [...], tol = t}, or
    :data:`Face` tuples) checked: one kind each, finite numbers of a 2D or 3D size, ``tol`` > 0."""
    if not faces:
        return ()
    if isinstance(faces, dict):
        items = list(faces.items())
    else:
        items = [(n, {k: list(v), **({} if t is None else {"tol": t})}) for n, k, v, t in faces]
    out = []
    for name, spec in items:
        what = f"domain.faces.{name}"
        if not isinstance(spec, dict):
            raise ExperimentError(f"{what} must be a table, e.g. {FACE_EXAMPLE}; got {spec!r}")
        spec = dict(spec)
        tol = spec.pop("tol", None)
        if len(spec) != 1 or next(iter(spec)) not in _FACE_SIZES:
            raise ExperimentError(f"{what} must hold one of box = [...] or plane = [...] (and tol with a plane), "
                                  f"e.g. {FACE_EXAMPLE}; got {sorted(spec)}")
        (kind, values), = spec.items()
        try:
            numbers = tuple(float(v) for v in values)
        except (TypeError, ValueError):
            raise ExperimentError(f"{what}.{kind} must be a list of numbers, got {values!r}") from None
        if len(numbers) not in _FACE_SIZES[kind] or not all(math.isfinite(v) for v in numbers):
            raise ExperimentError(f"{what}.{kind} must be {_FACE_SIZES[kind][1]} finite numbers (3D; "
                                  f"{_FACE_SIZES[kind][0]} in 2D), got {values!r}")
        if kind == "plane" and not any(numbers[:-1]):
            raise ExperimentError(f"{what}.plane's normal [nx, ny(, nz)] is zero")
        if tol is not None and (isinstance(tol, bool) or not isinstance(tol, (int, float)) or not tol > 0):
            raise ExperimentError(f"{what}.tol must be a positive number (length unit), got {tol!r}")
        out.append((str(name), kind, numbers, None if tol is None else float(tol)))
    return tuple(out)


def faces_to_toml(faces) -> dict:
    """The ``faces`` entry of a mesh domain's TOML table (empty when there are none)."""
    return {"faces": {n: {k: list(v), **({} if t is None else {"tol": t})} for n, k, v, t in faces}} if faces else {}


def with_domain_faces(mesh, faces):
    """``mesh`` (a :class:`jaxfem.Mesh`) with the faces of ``faces`` (:data:`Face` tuples) added to
    its own: the boundary facets all of whose nodes lie in the box or within ``tol`` of the plane.

    Raises:
        ExperimentError: a face of the wrong dimension, or one that selects no boundary facet (named,
            with the faces the mesh has).
    """
    if not faces:
        return mesh
    lo, hi = mesh.bounds()
    size = float(np.max(hi - lo))
    found = {}
    for name, kind, v, tol in faces:
        d = mesh.dim
        if len(v) != _FACE_SIZES[kind][d - 2]:
            raise ExperimentError(f"domain.faces.{name}.{kind} has {len(v)} numbers, but the mesh is {d}D: give "
                                  f"{_FACE_SIZES[kind][d - 2]}")
        if kind == "box":
            a, b = np.minimum(v[:d], v[d:]), np.maximum(v[:d], v[d:])
            pad = 1e-9 * size if tol is None else tol
            facets = mesh.facets_where(lambda x: np.all((x >= a - pad) & (x <= b + pad), axis=1))
        else:
            n = np.asarray(v[:d]) / np.linalg.norm(v[:d])
            off = v[d] / np.linalg.norm(v[:d])
            facets = mesh.facets_where(lambda x: np.abs(x @ n - off) <= (1e-9 * size if tol is None else tol))
        found[name] = facets
    empty = [n for n, f in found.items() if not len(f)]
    if empty:
        name, kind, v, _ = next(f for f in faces if f[0] == empty[0])
        named = [*mesh.faces, *(n for n, f in found.items() if len(f))]
        raise ExperimentError(
            f"domain.faces.{name} ({kind} {list(v)}) selects no boundary facet of the mesh (its bounds "
            f"{lo.round(6).tolist()} to {hi.round(6).tolist()}); faces that exist: "
            f"{named if named else 'none named'}, and the bounding box's sides "
            f"{[n for n in mesh.side_names() if n not in named]}")
    return mesh.with_faces(found)


def unknown_face(name: str, mesh) -> str:
    """The message for a face or side ``name`` a mesh domain does not have."""
    return (f"unknown face {name!r}: the mesh domain has {mesh.side_names()} (its named faces first, then the "
            f"bounding box's sides). Name it in the mesh file (a gmsh physical group of boundary facets) or in "
            f"experiment.toml: domain = {{ mesh = ..., {FACE_EXAMPLE.replace('NAME', name)} }}")
