"""Tracked points and their measured motion: the data every refinement fits.

The paper (Tsap, Goldgof & Sarkar 2000, Sec. 1.3 and 2.1) splits the correspondences into a set P
that drives the model (here role ``boundary``), a set Q that guides the search (``guide``) and a
held-out set for validation (``validate``). A point lost by the tracker in a frame has NaN
displacement in that frame; it is never zero-filled, because zero is a valid measurement.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from refine.bundle.roles import ROLES
from refine.exceptions import ObservationError


@dataclass(frozen=True, eq=False)
class Forces:
    """Measured total forces (load cell) across named sides of the domain, frame by frame.

    Attributes:
        edges: names of the sides, e.g. ``("right",)``; for a rectangle one of
            ``left``, ``right``, ``bottom``, ``top``.
        values: ``(n_frames, n_edges, dim)`` float64, total force crossing each side in each frame,
            in the bundle's force unit.
    """

    edges: tuple[str, ...]
    values: np.ndarray

    def __post_init__(self):
        edges = tuple(str(e) for e in self.edges)
        values = _readonly(np.asarray(self.values, dtype=np.float64))
        if len(set(edges)) != len(edges) or any(not e for e in edges):
            raise ObservationError(f"force edges must be distinct non-empty names, got {edges}")
        if values.ndim != 3 or values.shape[1] != len(edges) or values.shape[2] not in (2, 3):
            raise ObservationError(
                f"force values must have shape (n_frames, {len(edges)}, 2 or 3), got {values.shape}"
            )
        if not np.all(np.isfinite(values)):
            raise ObservationError("force values contain NaN or inf; every listed force must be a number")
        object.__setattr__(self, "edges", edges)
        object.__setattr__(self, "values", values)

    def on(self, edge: str) -> np.ndarray:
        """Force across ``edge`` in every frame, ``(n_frames, dim)``."""
        if edge not in self.edges:
            raise ObservationError(f"no force measured on edge {edge!r}; measured edges: {list(self.edges)}")
        return self.values[:, self.edges.index(edge)]


@dataclass(frozen=True, eq=False)
class Observations:
    """Tracked points in the reference configuration and their displacements in every frame.

    Attributes:
        ids: ``(n,)`` int64 point identifiers, unique.
        reference: ``(n, dim)`` float64 coordinates at frame 0 (dim 2 or 3), length unit.
        roles: ``(n,)`` str, each ``"boundary"`` | ``"guide"`` | ``"validate"``.
        displacements: ``(n_frames, n, dim)`` float64 displacement from the reference in frames
            1..n_frames; all components NaN where the point was lost in that frame.
        forces: optional :class:`Forces` with the same number of frames.
    """

    ids: np.ndarray
    reference: np.ndarray
    roles: np.ndarray
    displacements: np.ndarray
    forces: Forces | None = None

    def __post_init__(self):
        ids = np.asarray(self.ids)
        if ids.ndim != 1 or not (ids.size == 0 or np.issubdtype(ids.dtype, np.integer)):
            raise ObservationError(f"ids must be a 1-D integer array, got shape {ids.shape} dtype {ids.dtype}")
        ids = _readonly(ids.astype(np.int64))
        n = len(ids)
        unique, counts = np.unique(ids, return_counts=True)
        if np.any(counts > 1):
            raise ObservationError(f"duplicate point ids: {unique[counts > 1][:10].tolist()}")

        reference = _readonly(np.asarray(self.reference, dtype=np.float64))
        if reference.shape not in ((n, 2), (n, 3)):
            raise ObservationError(f"reference must have shape ({n}, 2 or 3), got {reference.shape}")
        if not np.all(np.isfinite(reference)):
            bad = ids[~np.isfinite(reference).all(axis=1)]
            raise ObservationError(f"reference coordinates contain NaN or inf (points {bad[:10].tolist()})")
        dim = reference.shape[1]

        roles = _readonly(np.asarray(self.roles, dtype=str))
        if roles.shape != (n,):
            raise ObservationError(f"roles must have shape ({n},), got {roles.shape}")
        unknown = sorted(set(roles.tolist()) - set(ROLES))
        if unknown:
            raise ObservationError(f"unknown roles {unknown}; a role is one of {list(ROLES)}")

        disp = _readonly(np.asarray(self.displacements, dtype=np.float64))
        if disp.ndim != 3 or disp.shape[1:] != (n, dim):
            raise ObservationError(f"displacements must have shape (n_frames, {n}, {dim}), got {disp.shape}")
        if np.any(np.isinf(disp)):
            frame, point = np.argwhere(np.isinf(disp))[0, :2]
            raise ObservationError(
                f"displacement of point {ids[point]} in frame {frame + 1} is infinite; "
                "use NaN (an empty cell in a bundle) for a lost point"
            )
        nan = np.isnan(disp)
        partial = nan.any(axis=2) & ~nan.all(axis=2)
        if np.any(partial):
            frame, point = np.argwhere(partial)[0]
            raise ObservationError(
                f"point {ids[point]} in frame {frame + 1} has some displacement components NaN and some "
                "not; a lost point has all components NaN"
            )
        if self.forces is not None:
            if not isinstance(self.forces, Forces):
                raise ObservationError(f"forces must be a Forces record or None, got {type(self.forces).__name__}")
            if self.forces.values.shape[0] != disp.shape[0] or self.forces.values.shape[2] != dim:
                raise ObservationError(
                    f"forces have shape {self.forces.values.shape} but there are {disp.shape[0]} frames "
                    f"in {dim}D; expected ({disp.shape[0]}, n_edges, {dim})"
                )
        object.__setattr__(self, "ids", ids)
        object.__setattr__(self, "reference", reference)
        object.__setattr__(self, "roles", roles)
        object.__setattr__(self, "displacements", disp)

    @property
    def n_points(self) -> int:
        """Number of tracked points n."""
        return len(self.ids)

    @property
    def dim(self) -> int:
        """Spatial dimension, 2 or 3."""
        return self.reference.shape[1]

    @property
    def n_frames(self) -> int:
        """Number of measured frames (frame 0, the reference, not counted)."""
        return self.displacements.shape[0]

    @property
    def frames(self) -> np.ndarray:
        """Frame numbers ``1..n_frames``, ``(n_frames,)`` int64, as in displacements.csv."""
        return np.arange(1, self.n_frames + 1, dtype=np.int64)

    @property
    def valid(self) -> np.ndarray:
        """``(n_frames, n)`` bool: True where the point was tracked in that frame."""
        return ~np.isnan(self.displacements[..., 0])

    @property
    def positions(self) -> np.ndarray:
        """Measured positions q = reference + displacement, ``(n_frames, n, dim)``, NaN where lost."""
        return self.reference[None] + self.displacements

    def mask(self, role: str) -> np.ndarray:
        """``(n,)`` bool selecting the points of ``role`` (``boundary``, ``guide`` or ``validate``)."""
        if role not in ROLES:
            raise ObservationError(f"unknown role {role!r}; a role is one of {list(ROLES)}")
        return self.roles == role

    def subset(self, role: str) -> Observations:
        """The points of one role only, same frames and forces."""
        keep = self.mask(role)
        return replace(
            self,
            ids=self.ids[keep],
            reference=self.reference[keep],
            roles=self.roles[keep],
            displacements=self.displacements[:, keep],
        )

    def index_of(self, ids) -> np.ndarray:
        """Row index of each id in ``ids`` (array-like of ints), ``(len(ids),)`` int64."""
        order = np.argsort(self.ids)
        wanted = np.asarray(ids, dtype=np.int64)
        pos = np.searchsorted(self.ids, wanted, sorter=order)
        pos = np.minimum(pos, len(order) - 1) if len(order) else pos
        found = len(order) > 0 and np.all(self.ids[order[pos]] == wanted)
        if not found:
            missing = np.setdiff1d(wanted, self.ids)
            raise ObservationError(f"unknown point ids {missing[:10].tolist()}")
        return order[pos]


def _readonly(a: np.ndarray) -> np.ndarray:
    a = np.array(a, copy=True)
    a.setflags(write=False)
    return a
