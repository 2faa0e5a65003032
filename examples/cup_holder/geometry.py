"""The cup holder of the paper's Sec. 4: a short thick-walled cylinder with a bottom, optionally
with a through-thickness elliptic hole in the bottom, meshed as a disc wall with a rim
(:func:`jaxfem.wall.rimmed_wall`), and its named node sets.

The axis is z; the bottom's outer face is the plane z = 0, the rim the plane z = ``height``.
Lengths are in the caller's unit (mm in the examples).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from jaxfem.exceptions import MeshError
from jaxfem.mesh import Mesh
from jaxfem.shapes import Ellipse
from jaxfem.wall import disc_wall, rimmed_wall

__all__ = ["CupHolder", "cup_bottom", "cup_holder"]

cup_bottom = disc_wall
"""The bottom slab of the cup holder :func:`cup_holder` meshes with the same arguments
(:func:`jaxfem.wall.disc_wall`: ``r_in, r_out, bottom, h, hole, ...``)."""


@dataclass(frozen=True)
class CupHolder:
    """A meshed cup holder and its named node sets.

    Attributes:
        mesh: the 3D mesh (``tet4`` or ``tet10``); region 0 is the bottom (z < ``bottom``), 1 the wall
            (``region_names`` ``{0: "bottom", 1: "wall"}``).
        sets: node indices by name, each sorted: ``"rim"`` (z = height), ``"bottom_outer"`` (z = 0),
            ``"bottom_inner"`` (the floor inside, z = bottom, r <= r_in), ``"wall_inner"`` (r = r_in,
            z >= bottom), ``"wall_outer"`` (r = r_out), ``"hole"`` (the hole's wall; empty without one).
        bottom_outer_facets: the boundary facets on z = 0, ``(n, 3 or 6)`` (a pushed bottom's load).
        r_in, r_out, height, bottom: the dimensions (length units).
        hole: the hole's :class:`Ellipse` in the (x, y) plane, or ``None``.
        plan: the ``tri3`` 2D mesh that was extruded (region 1 under the wall, so a morph of the
            hole keeps the wall's feet); column: ``(n_vertices,)`` the plan node under each vertex.
    """

    mesh: Mesh
    sets: dict
    bottom_outer_facets: np.ndarray
    r_in: float
    r_out: float
    height: float
    bottom: float
    hole: Ellipse | None = None
    plan: Mesh | None = None
    column: np.ndarray | None = None


def cup_holder(r_in: float, r_out: float, height: float, bottom: float, h: float, hole: Ellipse | None = None,
               element: str = "tet10", layers: int | None = None, hole_h: float | None = None,
               floor_h: float | None = None) -> CupHolder:
    """Mesh a cup holder of inner/outer radius ``r_in``/``r_out``, total ``height`` and ``bottom``
    thickness, target element size ``h`` (all length units), ``element`` ``"tet10"`` (default; the
    locking-free choice for nearly incompressible foams) or ``"tet4"``; ``hole``, ``layers``,
    ``hole_h``, ``floor_h`` as :func:`jaxfem.wall.rimmed_wall` takes them (the hole through the
    bottom inside the floor ``r < r_in``)."""
    if element not in ("tet4", "tet10"):
        raise MeshError(f"cup_holder() makes tet4 or tet10 meshes, not {element!r}")
    w = rimmed_wall(r_in, r_out, bottom, height, h, hole, element, layers, hole_h, floor_h,
                    names={0: "bottom", 1: "wall"})
    return CupHolder(w.mesh, _sets(w.mesh, r_in, r_out, height, bottom, hole), w.facets,
                     float(r_in), float(r_out), float(height), float(bottom), hole, w.plan, w.column)


def _sets(mesh, r_in, r_out, height, bottom, hole):
    X = mesh.nodes
    r, z = np.hypot(X[:, 0], X[:, 1]), X[:, 2]
    tol = 1e-9 * max(r_out, height)
    # mid-edge nodes of tet10 lie on chords of the circles: a chord's sagitta is within h^2 / (8 r)
    sag = 1e-3 * r_out + tol
    sets = {
        "rim": np.flatnonzero(np.abs(z - height) <= tol),
        "bottom_outer": np.flatnonzero(np.abs(z) <= tol),
        "bottom_inner": np.flatnonzero((np.abs(z - bottom) <= tol) & (r <= r_in + tol)),
        "wall_inner": np.flatnonzero((r >= r_in - _sagitta(mesh, r_in) - tol) & (r <= r_in + tol) & (z >= bottom - tol)),
        "wall_outer": np.flatnonzero(r >= r_out - _sagitta(mesh, r_out) - sag),
        "hole": np.zeros(0, np.int64),
    }
    if hole is not None:
        # vertices lie on the curve, mid-edge nodes on chords inside it (the ellipse is convex)
        bnd = mesh.boundary_nodes()
        grown = Ellipse(hole.cx, hole.cy, hole.rx + tol, hole.ry + tol, hole.angle)
        sets["hole"] = bnd[grown.contains(X[bnd, :2]) & (z[bnd] <= bottom + tol)]
    return {k: np.sort(v) for k, v in sets.items()}


def _sagitta(mesh, radius):
    """How far inside a circle of ``radius`` a straight edge's midpoint may lie (the longest
    boundary edge's sagitta, length units)."""
    f = mesh.boundary_facets()[:, :3]
    e = np.linalg.norm(mesh.nodes[f[:, 0]] - mesh.nodes[f[:, 1]], axis=1).max()
    return e * e / (8 * radius)

