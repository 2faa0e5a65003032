"""What a cup holder's model mesh says of it: its dimensions (the bottom the local model cuts out),
whether its surface closes, and which measured points lie on its bottom's outer face."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import jaxfem as jf

from refine.exceptions import ObservationError, RefineError


class MeshNotClosedError(RefineError, ValueError):
    """A 3D model mesh whose surface has holes or loose edges: not a solid body."""


@dataclass(frozen=True)
class CupShape:
    """A cup holder's dimensions read off its mesh (length unit): axis along z through ``centre``
    ``(x, y)``, bottom's outer face at ``z0``; inner and outer radius, height, bottom thickness."""

    centre: tuple[float, float]
    z0: float
    r_in: float
    r_out: float
    height: float
    bottom: float

    @property
    def offset(self) -> np.ndarray:
        """``(3,)``: where the cup frame's origin (bottom face's centre) lies."""
        return np.array([*self.centre, self.z0])


def check_closed(mesh: jf.Mesh) -> None:
    """Raise :class:`MeshNotClosedError` unless every edge of the mesh's surface is shared by
    exactly two boundary facets (a closed surface; a mesh with a missing cell or a gap is not)."""
    f = mesh.boundary_facets()[:, :3]
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    _, count = np.unique(e, axis=0, return_counts=True)
    bad = int((count != 2).sum())
    if bad:
        raise MeshNotClosedError(f"the model mesh's surface does not close: {bad} of its edges belong to "
                                 f"{'one' if (count == 1).any() else 'more than two'} surface facets; mesh the "
                                 "body as one conforming solid (e.g. examples.cup_holder.cup_holder) and write it again")


def cup_shape(mesh: jf.Mesh) -> CupShape:
    """The dimensions of a cup holder meshed with its axis along z (:class:`CupShape`): the axis
    through the volume's centroid, outer
    radius and height from the extent, bottom thickness from the lowest floor above the outer
    face, inner radius from the inner wall's nodes.

    Raises:
        ObservationError: the mesh is not 3D or has no floor and inner wall (not a cup holder)."""
    if mesh.dim != 3:
        raise ObservationError("a cup holder's model is a 3D mesh (model.kind = \"solid\")")
    lo, hi = mesh.bounds()
    vol = mesh.volumes()  # the axis: through the volume's centroid (a polygonal circle's box is lopsided)
    centre = (vol[:, None] * mesh.nodes[mesh.cells[:, :4]].mean(1)[:, :2]).sum(0) / vol.sum()
    X = mesh.nodes - [*centre, lo[2]]
    r, z = np.hypot(X[:, 0], X[:, 1]), X[:, 2]
    r_out, height = float(r.max()), float(z.max())
    tol = 1e-6 * max(r_out, height)
    b = mesh.boundary_nodes()
    sag = 0.02 * r_out  # mid-edge nodes of a polygonal circle lie inside it
    inside = b[(r[b] < r_out - sag) & (z[b] > tol) & (z[b] < height - tol)]
    if not len(inside):
        raise ObservationError("the model mesh has no floor and inner wall: not a cup holder (a cylinder with a "
                               "bottom, axis along z)")
    bottom = float(z[inside].min())
    wall = inside[z[inside] > bottom + tol]
    r_in = float(r[wall].max()) if len(wall) else float(r[inside].max())
    return CupShape((float(centre[0]), float(centre[1])), float(lo[2]), r_in, r_out, height, bottom)


def bottom_points(shape: CupShape, reference, tol: float) -> np.ndarray:
    """``(n,)`` bool: the points on the bottom's outer face (within ``tol`` of its plane, inside
    its disk), in the mesh's frame."""
    X = np.asarray(reference, float) - shape.offset
    return (np.abs(X[:, 2]) <= tol) & (np.hypot(X[:, 0], X[:, 1]) <= shape.r_out + tol)
