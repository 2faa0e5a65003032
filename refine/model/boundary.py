"""Where measured points meet the model's outline: how far off it they may lie, where they are
placed, and the named sides a measured force crosses.

Measured points never lie exactly on a drawn outline (a specimen's edge seen by DIC is a ragged
row of points; a nominal rectangle is not the cut specimen). A point within
:func:`outline_tolerance` of the outline is accepted: a boundary point drives the model where it
projects onto the outline (its measured displacement is the value there, interpolated along the
outline to the boundary nodes between it and its neighbours), and any point just outside the
mesh is compared with the model at its projection. Its position in the bundle is kept as given.
The drive error this makes is about the displacement gradient times the offset, which is why the
tolerance is a quarter of the point spacing unless the noise is larger; points farther off are
an error that names the worst one (build the domain from the points instead:
``domain = { from_points = "concave" }``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import jaxfem as jf

from refine.bundle.experiment import MeshDomain, RectangleDomain
from refine.bundle.sides import undefined_side, unknown_face, with_domain_faces
from refine.exceptions import ObservationError

SPACING_FRACTION = 0.25  # of the point spacing: how far a boundary point may lie off the outline
NOISE_MULTIPLE = 3.0  # or this many noise standard deviations, where that is more


def outline_tolerance(spacing: float, noise_std: float | None) -> float:
    """How far from the domain's outline a boundary point may lie (length unit):
    ``max(3 noise_std, 0.25 spacing)`` (``noise_std`` None or 0: the spacing term alone)."""
    return max(NOISE_MULTIPLE * (noise_std or 0.0), SPACING_FRACTION * spacing)


@dataclass(frozen=True, eq=False)
class Placement:
    """The tracked points placed on a model's mesh.

    Attributes:
        positions: ``(n, 2)`` where each point is compared with the model: its reference position,
            or its projection onto the outline where it lies just outside the mesh.
        offsets: ``(n,)`` distance of each boundary point from the outline (0 for other points).
        tolerance: the largest offset allowed (:func:`outline_tolerance`).
    """

    positions: np.ndarray
    offsets: np.ndarray
    tolerance: float


def place_points(mesh: jf.Mesh, reference, boundary, ids, tolerance: float) -> Placement:
    """Place 2D points on ``mesh`` (see :class:`Placement`).

    Args:
        mesh: the model's mesh; reference: ``(n, 2)`` point positions; boundary: ``(n,)`` bool,
        the driving points; ids: ``(n,)`` point ids; tolerance: length unit.

    Raises:
        ObservationError: a boundary point farther than ``tolerance`` from the outline, or another
            point farther than that outside it (the worst point named, with its distance).
    """
    from matplotlib.path import Path

    pts = np.asarray(reference, np.float64)
    pr = jf.project_to_boundary(mesh, pts)
    outside = ~Path(mesh.nodes[pr.loop]).contains_points(pts) & (pr.distance > 1e-9 * np.ptp(pts, axis=0).max())
    for bad, what in ((boundary & (pr.distance > tolerance), "boundary points are not on the domain's outline"),
                      (~boundary & outside & (pr.distance > tolerance), "points lie outside the domain")):
        if bad.any():
            worst = np.flatnonzero(bad)[np.argmax(pr.distance[bad])]
            raise ObservationError(
                f"{int(bad.sum())} {what}: the farthest, point {ids[worst]}, is {pr.distance[worst]:.3g} away (allowed: "
                f"{tolerance:.3g}, the larger of {NOISE_MULTIPLE:g} noise_std and {SPACING_FRACTION:g} x the point "
                "spacing). Correct the domain's outline, build it from the points (domain = { from_points = "
                "\"concave\" }), or give such points another role")
    positions = np.where(outside[:, None], pr.foot, pts)
    return Placement(positions, np.where(boundary, pr.distance, 0.0), tolerance)


def place_surface_points(mesh: jf.Mesh, reference, boundary, ids, tolerance: float, domain=None) -> Placement:
    """Place 3D points on a solid ``mesh``: the 3D counterpart of :func:`place_points`. Measured
    surface points (range images, stereo) lie off the faceted model surface by their noise and by
    the facets' chords: a boundary point is compared and drives the model at its projection onto
    the surface; another point inside the mesh (e.g. a digital volume correlation's) stays where it
    is and is compared there, one outside is projected.

    Args:
        domain: the experiment's domain; where it is a :class:`MeshDomain` with ``boundary_faces``,
            every boundary point must lie within ``tolerance`` of one of those faces.

    Raises:
        ObservationError: a boundary point farther than ``tolerance`` from the surface (or from the
            domain's boundary faces), or another point farther than that outside it (the worst
            point named, with its distance).
    """
    from jaxfem.probe import find_cells
    from jaxfem.surface import project_to_surface

    pts = np.asarray(reference, np.float64)
    foot, dist = project_to_surface(mesh, pts)
    outside = find_cells(mesh, pts)[2] > 1e-9
    for bad, what in ((boundary & (dist > tolerance), "boundary points are not on the mesh's surface"),
                      (~boundary & outside & (dist > tolerance), "points lie outside the mesh")):
        if bad.any():
            worst = np.flatnonzero(bad)[np.argmax(dist[bad])]
            raise ObservationError(
                f"{int(bad.sum())} {what}: the farthest, point {ids[worst]}, is {dist[worst]:.3g} away (allowed: "
                f"{tolerance:.3g}, the larger of {NOISE_MULTIPLE:g} noise_std and {SPACING_FRACTION:g} x the point "
                "spacing). Check that the mesh and the points share their axes and units (the camera's pose), "
                "or give such points another role")
    names = getattr(domain, "boundary_faces", ())
    if names and boundary.any():
        per_face = face_distance(mesh, domain, names, pts[boundary])
        empty = [n for n, d in zip(names, per_face) if not (d <= tolerance).any()]
        if empty:
            raise ObservationError(f"no boundary point lies on the face(s) {empty} of domain.boundary_faces (within "
                                   f"{tolerance:.3g}), whose every node the points would drive; name only the faces "
                                   "the boundary points lie on")
        off = per_face.min(axis=0)
        if (off > tolerance).any():
            worst = np.argmax(off)
            raise ObservationError(
                f"{int((off > tolerance).sum())} boundary points are not on the faces {list(names)} "
                f"(domain.boundary_faces): the farthest, point {ids[boundary][worst]}, is {off[worst]:.3g} away "
                f"(allowed: {tolerance:.3g}). Name the faces they lie on, or give such points another role")
    move = boundary | outside
    return Placement(np.where(move[:, None], foot, pts), np.where(boundary, dist, 0.0), tolerance)


def side_nodes(mesh: jf.Mesh, domain, name: str) -> np.ndarray:
    """The nodes of the side ``name`` of ``domain`` on ``mesh`` (whose reactions sum to the force
    across it), ``(k,)``: a rectangle's ``left``/``right``/``bottom``/``top``, a mesh domain's
    named faces (:func:`face_facets`) and bounding-box sides, or a side the domain names
    (:mod:`refine.bundle.sides`): the outer boundary nodes from the first end's projection
    counter-clockwise to the second's.

    Raises:
        ObservationError: the domain does not define the side (no guess is made).
    """
    if isinstance(domain, MeshDomain):
        faces = _faces(mesh, domain)
        return np.unique(faces[name]) if name in faces else _box_side(mesh.with_faces(faces), name)
    named = {n: (a, b) for n, a, b in getattr(domain, "sides", ())}
    if name not in named:
        if isinstance(domain, RectangleDomain) and name in domain.side_names:
            return mesh.side(name)
        raise ObservationError(undefined_side(name, domain.side_names))
    ends = [domain.vertices[e] if isinstance(e, int) else e for e in named[name]]  # a vertex index: a polygon's
    pr = jf.project_to_boundary(mesh, np.asarray(ends, np.float64))
    s0, s1 = pr.arc
    span = (s1 - s0) % pr.perimeter
    tol = 1e-9 * pr.perimeter
    along = (pr.node_arc - s0) % pr.perimeter
    nodes = pr.loop[(along <= span + tol) | (along >= pr.perimeter - tol)]
    if len(nodes) < 2:
        raise ObservationError(f"the side {name!r} spans fewer than two nodes of the model's outline; give ends "
                               "farther apart")
    return nodes


def _faces(mesh: jf.Mesh, domain) -> dict:
    """The named faces of ``mesh`` and of the domain's experiment.toml (those win), ``{name: facets}``."""
    return with_domain_faces(mesh, getattr(domain, "faces", ())).faces


def _box_side(mesh: jf.Mesh, name: str) -> np.ndarray:
    try:
        return mesh.side(name)
    except jf.MeshError:
        raise ObservationError(unknown_face(name, mesh)) from None


def face_facets(mesh: jf.Mesh, domain, name: str) -> np.ndarray:
    """The boundary facets of a mesh domain's face or side ``name``, ``(k, nodes_per_facet)``: a face
    named in experiment.toml (``domain.faces``), else one the mesh file names (``mesh.faces``), else
    a side of the mesh's bounding box.

    Raises:
        ObservationError: no such face (the faces there are listed); ExperimentError: a face of
            ``domain.faces`` selects nothing.
    """
    faces = _faces(mesh, domain)
    if name in faces:
        return faces[name]
    facets = mesh.side_facets(name) if name in mesh.side_names() else None
    if facets is None or not len(facets):
        raise ObservationError(unknown_face(name, mesh.with_faces(faces)) if facets is None else
                               f"the bounding-box side {name!r} holds no boundary facet of the mesh (a curved or "
                               "tilted body?); name the face in the mesh file or in experiment.toml's domain.faces")
    return facets


def face_distance(mesh: jf.Mesh, domain, names, points) -> np.ndarray:
    """Each 3D point's distance to each of the faces ``names`` (:func:`face_facets`), ``(len(names), n)``."""
    from jaxfem.surface import project_to_surface

    pts = np.asarray(points, np.float64)
    return np.array([project_to_surface(mesh, pts, facets=face_facets(mesh, domain, n))[1] for n in names])


def boundary_face_nodes(mesh: jf.Mesh, domain) -> np.ndarray | None:
    """The nodes a 3D model's boundary points drive where the domain ties them to faces: every node
    of its ``boundary_faces`` (each interpolated from its nearest boundary points), sorted; None
    without such faces (or in 2D): the surface nodes near the points."""
    names = getattr(domain, "boundary_faces", ())
    if mesh.dim != 3 or not names:
        return None
    return np.unique(np.concatenate([face_facets(mesh, domain, n) for n in names]))
