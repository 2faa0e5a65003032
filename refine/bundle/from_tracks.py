"""A measurement bundle from tracked points (:class:`tracking.Tracks` in length units).

The tracked points' outer ring becomes the boundary (the paper's set P), so the domain is the
outline through that ring: a rectangle when the ring is one (to :data:`RECTANGLE_TOLERANCE` of the
point spacing), else a polygon through the ring points. The model sections come from a
:class:`ModelSkeleton` and are only a starting point for the user to check.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from refine.bundle.experiment import Experiment, PolygonDomain, RectangleDomain
from refine.bundle.io import Bundle
from refine.bundle.observations import Observations
from refine.bundle.roles import assign_roles, point_spacing
from refine.bundle.outline import walk_loops
from refine.exceptions import ObservationError

if TYPE_CHECKING:  # refine reads tracking's output; nothing here needs the package at run time
    from tracking import Tracks

RECTANGLE_TOLERANCE = 0.02  # of the point spacing: how far ring points may stray from a rectangle


@dataclass(frozen=True)
class ModelSkeleton:
    """The initial model written to experiment.toml (to be checked by the user).

    Attributes:
        kind: ``"plane-stress"`` or ``"plane-strain"``.
        law: a material law of :data:`jaxfem.materials.LAWS`.
        E: background Young's modulus (relative when the bundle has no measured forces).
        nu: Poisson's ratio.
        thickness: sheet thickness, in the bundle's length unit.
        noise_std: displacement noise, length unit; None lets ``nonrigid diagnose`` estimate it.
    """

    kind: str = "plane-stress"
    law: str = "neo-hookean"
    E: float = 1.0
    nu: float = 0.3
    thickness: float = 1.0
    noise_std: float | None = None


def bundle_from_tracks(tracks: Tracks, name: str, model: ModelSkeleton = ModelSkeleton(),
                       validate_fraction: float = 0.2, seed: int = 0, holes=()) -> tuple[Bundle, np.ndarray]:
    """A bundle of tracked points in length units (see :meth:`tracking.Tracks.to_length`).

    The boundary is the outline through the outer ring of the lattice (``grid_index``; the convex
    hull without a lattice); interior points are split into guide and validate points by
    :func:`refine.bundle.roles.assign_roles` (``validate_fraction`` of them, drawn under ``seed``).
    Points outside that outline (tracked crossings that belong to no cell of the lattice) cannot be
    compared with a model and are left out. ``holes`` (polygons ``(m, 2)`` in the tracks' length
    unit, e.g. a tracker's ``meta["outline"]["holes"]`` converted) are cut from the domain where
    they lie inside its outline; points inside a hole are left out too.

    Returns:
        The bundle (not written; see :func:`refine.bundle.io.write_bundle`) and the ids of the
        points left out, ``(k,)``.

    Raises:
        ObservationError: the tracks have a single frame, or their points form no lattice cell.
    """
    if tracks.n_frames < 2:
        raise ObservationError("the tracks have only the reference frame; a bundle needs at least one more")
    reference = tracks.reference
    loop = lattice_outline(tracks.grid_index) if np.all(tracks.grid_index >= 0) else _hull_loop(reference)
    ring = reference[loop]
    if _signed_area(ring) < 0:
        loop, ring = loop[::-1], ring[::-1]
    inside = _strictly_inside(ring, reference)
    inside[loop] = True
    cut = [np.asarray(h, dtype=np.float64) for h in holes
           if len(h) >= 3 and _strictly_inside(ring, np.asarray(h, dtype=np.float64)).all()]
    for h in cut:
        inside &= ~_strictly_inside(h if _signed_area(h) > 0 else h[::-1], reference)
    roles = assign_roles(reference, validate_fraction, seed, tracks.grid_index)
    roles[(roles == "boundary")] = "guide"  # only the outline's own points drive the model
    roles[loop] = "boundary"
    keep = np.flatnonzero(inside)
    lo, hi = reference[keep].min(axis=0), reference[keep].max(axis=0)
    off = np.min(np.abs(np.concatenate([ring - lo, ring - hi], axis=1)), axis=1)
    if off.max() <= RECTANGLE_TOLERANCE * point_spacing(reference[keep]):
        domain = RectangleDomain(*lo, *hi, holes=tuple(tuple(map(tuple, h)) for h in cut))
    else:
        domain = PolygonDomain(tuple(map(tuple, ring)), holes=tuple(tuple(map(tuple, h)) for h in cut))
    obs = Observations(ids=tracks.ids[keep], reference=reference[keep], roles=roles[keep],
                       displacements=tracks.displacements()[1:, keep])
    experiment = Experiment(name=name, kind=model.kind, domain=domain, law=model.law, E=model.E, nu=model.nu,
                            thickness=model.thickness, units={"length": tracks.units}, noise_std=model.noise_std,
                            subset=subset_size(tracks))
    return Bundle(experiment, obs), tracks.ids[~inside]


def subset_size(tracks: Tracks) -> float | None:
    """The side of the square subset (window) the tracker correlated around each point, in the
    tracks' length unit (``meta["subset_px"]`` times ``meta["scale_per_px"]`` where they were
    converted to lengths); None where the tracker did not say (a grid tracker, a CSV export)."""
    px = tracks.meta.get("subset_px")
    if px is None:
        return None
    return float(px) * float(tracks.meta.get("scale_per_px", 1.0))


def lattice_outline(grid_index: np.ndarray) -> np.ndarray:
    """Indices of the points on the outer outline of a lattice, in order around it, ``(m,)`` int.

    The lattice's cells are the squares whose four corners are all points (``grid_index``
    (n, 2) holds each point's (row, col)); the outline is the boundary of their union, traced
    with the cells on its left. Where two parts of the union touch at a single corner the trace
    keeps to one part; the largest loop is returned.

    Raises:
        ObservationError: the points form no cell.
    """
    index = np.asarray(grid_index, dtype=np.int64)
    lookup = {tuple(ij): k for k, ij in enumerate(index)}
    edges = set()
    for i, j in lookup:
        square = [(i, j), (i, j + 1), (i + 1, j + 1), (i + 1, j)]
        if all(c in lookup for c in square):
            edges.update(zip(square, square[1:] + square[:1]))
    edges = {e for e in edges if e[::-1] not in edges}
    if not edges:
        raise ObservationError("the tracked points form no cell of a lattice (too few points); enlarge the ROI")
    leaving: dict = {}
    for a, b in edges:
        leaving.setdefault(a, []).append(b)
    loops = walk_loops(leaving, lambda a, b: (b[0] - a[0], b[1] - a[1]), _turn)
    largest = max(loops, key=lambda lp: abs(_signed_area(np.array(lp, float))))
    return np.array([lookup[v] for v in largest])


def _turn(heading, direction) -> float:
    """Left turn from ``heading`` to ``direction`` (lattice steps (di, dj)) in radians, in the
    (x = j, y = i) frame in which the cells lie on the left of the outline."""
    if heading is None:
        return 0.0
    cross = heading[1] * direction[0] - heading[0] * direction[1]
    return float(np.arctan2(cross, heading[0] * direction[0] + heading[1] * direction[1]))


def _hull_loop(points: np.ndarray) -> np.ndarray:
    """Without a lattice: the points on the convex hull, in order around it."""
    from scipy.spatial import ConvexHull

    return ConvexHull(points).vertices


def _signed_area(ring: np.ndarray) -> float:
    x, y = ring[:, 0], ring[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def _strictly_inside(ring: np.ndarray, points: np.ndarray) -> np.ndarray:
    from matplotlib.path import Path as Outline

    return Outline(ring).contains_points(points)
