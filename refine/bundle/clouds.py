"""Unlabelled observations: point clouds with no identities (range scans, outlines, samples of a
texture-less surface), one per frame, frame 0 the reference shape.

They are kept in a bundle's optional ``clouds.csv`` (``frame,x,y[,z]``), beside or instead of the
tracked points of ``points.csv`` (see docs/measurement-bundle.md). A point of one frame has no
relation to any point of another frame: recovering that relation (the dense correspondences) is
what :mod:`refine.correspond` does.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from refine.exceptions import BundleError, ObservationError

__all__ = ["Clouds", "check_frames", "read_clouds", "write_clouds"]

_AXES = ("x", "y", "z")


@dataclass(frozen=True, eq=False)
class Clouds:
    """One point cloud per frame, frame 0 the reference configuration.

    Attributes:
        points: tuple of ``(n_k, dim)`` float64 arrays, length unit; entry k is frame k. Frames may
            hold different numbers of points; every frame holds at least one.
    """

    points: tuple

    def __post_init__(self):
        frames = []
        for k, p in enumerate(self.points):
            p = np.array(p, dtype=np.float64)
            if p.ndim != 2 or p.shape[1] not in (2, 3):
                raise ObservationError(f"cloud of frame {k} must have shape (n, 2 or 3), got {p.shape}")
            if len(p) == 0:
                raise ObservationError(f"cloud of frame {k} is empty; every frame from 0 (the reference shape) "
                                       "to the last needs at least one point")
            if not np.all(np.isfinite(p)):
                row = int(np.flatnonzero(~np.isfinite(p).all(axis=1))[0])
                raise ObservationError(f"cloud of frame {k} has NaN or inf coordinates (point {row}); an unlabelled "
                                       "point that was not seen is simply left out")
            p.setflags(write=False)
            frames.append(p)
        if len(frames) < 2:
            raise ObservationError(f"clouds need frame 0 (the reference shape) and at least one deformed frame, "
                                   f"got {len(frames)} frame(s)")
        dims = {p.shape[1] for p in frames}
        if len(dims) > 1:
            raise ObservationError(f"clouds mix 2D and 3D frames ({sorted(dims)}); every frame has the same axes")
        object.__setattr__(self, "points", tuple(frames))

    @property
    def dim(self) -> int:
        """Spatial dimension, 2 or 3."""
        return self.points[0].shape[1]

    @property
    def n_frames(self) -> int:
        """Number of deformed frames (frame 0, the reference, not counted), as for Observations."""
        return len(self.points) - 1

    def frame(self, k: int) -> np.ndarray:
        """The cloud of frame ``k`` (0 = reference), ``(n_k, dim)``."""
        if not 0 <= k < len(self.points):
            raise ObservationError(f"no cloud for frame {k}; frames are 0..{len(self.points) - 1}")
        return self.points[k]


def check_frames(clouds: Clouds | None, n_frames: int) -> None:
    """Raise :class:`ObservationError` when the clouds and the tracked points (``n_frames``
    deformed frames in displacements.csv) do not cover the same frames: frame k of both is one
    moment of the experiment, so a frame missing from one of them would pair the wrong moments."""
    if clouds is not None and clouds.n_frames != n_frames:
        raise ObservationError(f"clouds.csv has frames 0..{clouds.n_frames} but displacements.csv has frames "
                               f"1..{n_frames}: both must cover the same frames (frame k of both is the same moment); "
                               "add the missing frames or cut the longer file to the shorter")


def read_clouds(path: str | Path, dim: int | None = None) -> Clouds | None:
    """Read ``clouds.csv`` (a file, or a bundle directory holding one); None where there is none.

    Raises :class:`BundleError` naming the line for a malformed row, and when a frame between 0 and
    the last has no point.
    """
    path = Path(path)
    if path.is_dir():
        path = path / "clouds.csv"
    if not path.exists():
        return None
    with open(path, newline="", encoding="utf-8-sig") as f:
        reader = csv.reader(f)
        header = [c.strip() for c in next(reader, [])]
        if header not in (["frame", "x", "y"], ["frame", "x", "y", "z"]):
            raise BundleError(path, f"header must be frame,x,y or frame,x,y,z, got {','.join(header)!r}", 1)
        if dim is not None and len(header) - 1 != dim:
            raise BundleError(path, f"has {len(header) - 1}D points but the model is {dim}D", 1)
        rows: dict[int, list] = {}
        for cells in reader:
            cells = [c.strip() for c in cells]
            if not any(cells):
                continue
            line = reader.line_num
            if len(cells) != len(header):
                raise BundleError(path, f"expected {len(header)} values ({','.join(header)}), got {len(cells)}", line)
            try:
                frame = int(cells[0])
            except ValueError:
                raise BundleError(path, f"frame = {cells[0]!r} is not an integer", line) from None
            if frame < 0:
                raise BundleError(path, f"frame {frame} is negative; frame 0 is the reference shape", line)
            xyz = []
            for cell, axis in zip(cells[1:], header[1:]):
                try:
                    value = float(cell)
                except ValueError:
                    raise BundleError(path, f"{axis} = {cell!r} is not a number", line) from None
                if not math.isfinite(value):
                    raise BundleError(path, f"{axis} = {cell!r}: NaN or inf; leave an unseen point out", line)
                xyz.append(value)
            rows.setdefault(frame, []).append(xyz)
    if not rows:
        raise BundleError(path, "lists no points; delete the file if no clouds were measured")
    missing = sorted(set(range(max(rows) + 1)) - set(rows))
    if missing:
        raise BundleError(path, f"frame {missing[0]} has no point (frames present: {sorted(rows)[:10]}); frames "
                                "are numbered 0 (the reference shape), 1, 2, ... without gaps")
    try:
        return Clouds(tuple(np.array(rows[k]) for k in range(max(rows) + 1)))
    except ObservationError as e:
        raise BundleError(path, str(e)) from None


def write_clouds(path: str | Path, clouds: Clouds) -> Path:
    """Write ``clouds`` as ``clouds.csv`` (into ``path`` if it is a directory); returns the file."""
    path = Path(path)
    if path.is_dir():
        path = path / "clouds.csv"
    with open(path, "w", newline="", encoding="utf-8") as f:
        out = csv.writer(f, lineterminator="\n")
        out.writerow(["frame", *_AXES[: clouds.dim]])
        for k, p in enumerate(clouds.points):
            for row in p:
                out.writerow([k, *map(repr, row.tolist())])
    return path
