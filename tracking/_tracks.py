"""The result of every tracker: points with identities, positions per frame, lost flags, quality."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ._errors import TrackingError


def _frozen(array, dtype) -> np.ndarray:
    out = np.array(array, dtype=dtype, copy=True)
    out.setflags(write=False)
    return out


@dataclass(frozen=True)
class Tracks:
    """Tracked points through an image sequence.

    Coordinates are image coordinates: x = column, y = row, the centre of the top-left pixel at
    (0, 0), in ``units`` (pixels unless converted with :meth:`to_length`). Lost points keep their
    row: a lost point has ``lost[f, i] = True`` and NaN in ``positions[f, i]``; nothing is dropped.

    Attributes:
        ids: (n,) int, stable identity of every point.
        reference: (n, 2) float, positions in frame 0 (x, y).
        positions: (n_frames, n, 2) float, positions in every frame, frame 0 included; NaN where lost.
        lost: (n_frames, n) bool, True where the tracker could not place the point.
        quality: (n_frames, n) float, tracker-specific, higher is better (see ``quality_kind``):
            ``"zncc"`` for the speckle tracker (zero-normalised cross-correlation, -1..1),
            ``"symmetry"`` for the grid tracker (fraction of the local line-profile variance that is
            mirror symmetric about the fitted lines, 0..1; typically > 0.99, the tracker loses a
            crossing under 0.8), ``"peak-sharpness"`` (0..1, relative to the frame's median) for
            its Hessian refiner, ``"snake"`` (1 where found) for snake crossings alone.
        grid_index: (n, 2) int, (row, column) of the point in the grid topology (grid tracker) or in
            the lattice of correlation points (speckle tracker); -1 where there is none.
        units: length unit of the coordinates ("px" or what :meth:`to_length` was given).
        quality_kind: what ``quality`` measures.
        meta: facts about the run (tracker, grid pitch and line width in px, subset size...).
    """

    ids: np.ndarray
    reference: np.ndarray
    positions: np.ndarray
    lost: np.ndarray
    quality: np.ndarray
    grid_index: np.ndarray
    units: str = "px"
    quality_kind: str = ""
    meta: dict = field(default_factory=dict, compare=False)

    def __post_init__(self):
        ids = _frozen(self.ids, np.int64)
        n = ids.shape[0]
        reference = _frozen(self.reference, np.float64)
        positions = _frozen(self.positions, np.float64)
        lost = _frozen(self.lost, bool)
        quality = _frozen(self.quality, np.float64)
        grid_index = _frozen(self.grid_index, np.int64)
        if ids.ndim != 1 or reference.shape != (n, 2) or grid_index.shape != (n, 2):
            raise TrackingError(
                f"Tracks: ids {ids.shape}, reference {reference.shape} and grid_index "
                f"{grid_index.shape} must be (n,), (n, 2), (n, 2)")
        if positions.ndim != 3 or positions.shape[1:] != (n, 2):
            raise TrackingError(f"Tracks: positions {positions.shape} must be (n_frames, {n}, 2)")
        if lost.shape != positions.shape[:2] or quality.shape != positions.shape[:2]:
            raise TrackingError(
                f"Tracks: lost {lost.shape} and quality {quality.shape} must be {positions.shape[:2]}")
        if len(np.unique(ids)) != n:
            raise TrackingError("Tracks: ids must be unique")
        if np.any(np.isnan(positions[~lost])):
            raise TrackingError("Tracks: a point that is not lost has a NaN position")
        if np.any(np.isfinite(positions[lost])):
            raise TrackingError("Tracks: a lost point must have a NaN position")
        object.__setattr__(self, "meta", dict(self.meta))
        for name, value in (("ids", ids), ("reference", reference), ("positions", positions),
                            ("lost", lost), ("quality", quality), ("grid_index", grid_index)):
            object.__setattr__(self, name, value)

    @property
    def n_frames(self) -> int:
        return self.positions.shape[0]

    @property
    def n_points(self) -> int:
        return self.positions.shape[1]

    def displacements(self) -> np.ndarray:
        """Displacement of every point from frame 0, (n_frames, n, 2), NaN where lost, in ``units``."""
        return self.positions - self.reference[None]

    def reliable(self, min_quality: float) -> np.ndarray:
        """(n_frames, n) bool: not lost and ``quality >= min_quality`` (the rest is doubtful)."""
        return ~self.lost & (self.quality >= min_quality)

    def to_length(self, scale_mm_per_px: float, origin=(0.0, 0.0), units: str = "mm") -> "Tracks":
        """The same tracks in length units: x = (col - origin_x) * scale, y = (row - origin_y) * scale.

        Args:
            scale_mm_per_px: length of one pixel (e.g. mm/px; see :func:`scale_from_grid`).
            origin: (x, y) in pixels that becomes (0, 0).
            units: name of the length unit, stored in ``units``.
        """
        if self.units != "px":
            raise TrackingError(f"to_length: tracks are already in {self.units!r}, not pixels")
        scale = float(scale_mm_per_px)
        if not np.isfinite(scale) or scale <= 0:
            raise TrackingError(f"to_length: scale must be a positive number, got {scale_mm_per_px}")
        shift = np.asarray(origin, dtype=np.float64).reshape(2)
        return replace(self, reference=(self.reference - shift) * scale,
                       positions=(self.positions - shift) * scale, units=units,
                       meta={**self.meta, "scale_per_px": scale, "origin_px": tuple(shift)})


def scale_from_grid(tracks: Tracks, pitch_mm: float) -> float:
    """Length per pixel (e.g. mm/px) from the known grid pitch and the tracked reference grid.

    The pixel pitch is the median distance between neighbouring grid points (same row, adjacent
    columns, or the reverse) in frame 0.

    Args:
        tracks: grid tracks in pixels (``grid_index`` set).
        pitch_mm: the physical distance between neighbouring grid lines.
    """
    index = tracks.grid_index
    if np.any(index < 0) or tracks.units != "px":
        raise TrackingError("scale_from_grid needs grid tracks in pixels (grid_index set for all points)")
    lookup = {tuple(ij): k for k, ij in enumerate(index)}
    distances = []
    for k, (i, j) in enumerate(index):
        for neighbour in ((i, j + 1), (i + 1, j)):
            other = lookup.get(neighbour)
            if other is not None:
                distances.append(np.linalg.norm(tracks.reference[other] - tracks.reference[k]))
    if not distances:
        raise TrackingError("scale_from_grid: no two neighbouring grid points in the tracks")
    return float(pitch_mm) / float(np.median(distances))
