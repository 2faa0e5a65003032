"""Read and write measurement bundles (see docs/measurement-bundle.md).

A bundle is a directory of plain text files: experiment.toml, points.csv, displacements.csv and
optionally forces.csv and a mesh file. Every problem found while reading raises
:class:`~refine.exceptions.BundleError` naming the file, the line and what to change.
"""

from __future__ import annotations

import csv
import math
import shutil
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import tomli_w

from refine.exceptions import BundleError, ExperimentError, ObservationError
from refine.bundle.experiment import Experiment, MeshDomain
from refine.bundle.clouds import Clouds, check_frames, read_clouds, write_clouds
from refine.bundle.sides import undefined_side
from refine.bundle.observations import Forces, Observations
from refine.bundle.roles import ROLES

__all__ = ["Bundle", "Experiment", "read_bundle", "write_bundle", "write_displacements_csv"]

_AXES = ("x", "y", "z")


@dataclass(frozen=True, eq=False)
class Bundle:
    """A measurement bundle in memory.

    Attributes:
        experiment: the content of experiment.toml.
        observations: points, roles, displacements (and forces) of all frames.
        root: the directory it was read from (used to find and copy a mesh file), or None.
        clouds: optional unlabelled point clouds (clouds.csv); a bundle of clouds only has
            ``observations`` None.
    """

    experiment: Experiment
    observations: Observations | None
    root: Path | None = None
    clouds: Clouds | None = None


def read_bundle(path: str | Path) -> Bundle:
    """Read the bundle in directory ``path``; raises BundleError on any malformed content."""
    root = Path(path)
    if not root.is_dir():
        raise BundleError(root, "is not a directory; a bundle is a directory holding experiment.toml, "
                                "points.csv and displacements.csv")
    experiment = _read_experiment(root / "experiment.toml")
    if isinstance(experiment.domain, MeshDomain) and not (root / experiment.domain.path).is_file():
        raise BundleError(root / "experiment.toml", f"model.domain names mesh file {experiment.domain.path!r}, "
                                                    f"which is not in {root}")
    if experiment.mesh is not None and not (root / experiment.mesh).is_file():
        raise BundleError(root / "experiment.toml", f"model.mesh names mesh file {experiment.mesh!r}, which is not "
                                                    f"in {root}")
    clouds = read_clouds(root, experiment.dim)
    if clouds is not None and not (root / "points.csv").exists():
        return Bundle(experiment, None, root=root, clouds=clouds)
    ids, reference, roles = _read_points(root / "points.csv", experiment.dim)
    displacements = _read_displacements(root / "displacements.csv", ids, experiment.dim)
    try:
        check_frames(clouds, len(displacements))
    except ObservationError as e:
        raise BundleError(root / "clouds.csv", str(e)) from None
    forces = None
    if (root / "forces.csv").exists():
        forces = _read_forces(root / "forces.csv", len(displacements), experiment.dim, experiment.domain.side_names)
    return Bundle(experiment, Observations(ids, reference, roles, displacements, forces), root=root, clouds=clouds)


def write_bundle(path: str | Path, bundle: Bundle) -> Path:
    """Write ``bundle`` into directory ``path`` (created if needed); ``read_bundle`` gives it back.

    A mesh file named by the domain is copied from ``bundle.root`` when that is another directory.
    Returns the directory.
    """
    root = Path(path)
    root.mkdir(parents=True, exist_ok=True)
    exp, obs = bundle.experiment, bundle.observations
    if obs is None and bundle.clouds is None:
        raise ObservationError("a bundle needs tracked points (observations) or clouds, or both")
    if obs is not None and obs.dim != exp.dim:
        raise ObservationError(f"observations are {obs.dim}D but model.kind {exp.kind!r} is {exp.dim}D")
    if obs is not None and exp.domain.side_names is not None and obs.forces is not None:
        unknown = sorted(set(obs.forces.edges) - set(exp.domain.side_names))
        if unknown:
            raise ObservationError(undefined_side(unknown[0], exp.domain.side_names))
    if obs is not None:
        check_frames(bundle.clouds, len(obs.displacements))
    (root / "experiment.toml").write_text(tomli_w.dumps(exp.to_toml()), encoding="utf-8")
    if bundle.clouds is not None:
        write_clouds(root / "clouds.csv", bundle.clouds)
    if obs is None:
        return root
    axes = _AXES[: obs.dim]
    with open(root / "points.csv", "w", newline="", encoding="utf-8") as f:
        out = csv.writer(f, lineterminator="\n")
        out.writerow(["id", *axes, "role"])
        for pid, xyz, role in zip(obs.ids, obs.reference, obs.roles):
            out.writerow([int(pid), *map(repr, xyz.tolist()), str(role)])
    write_displacements_csv(root / "displacements.csv", obs.ids, obs.displacements)
    if obs.forces is not None:
        with open(root / "forces.csv", "w", newline="", encoding="utf-8") as f:
            out = csv.writer(f, lineterminator="\n")
            out.writerow(["frame", "edge", *(f"f{a}" for a in axes)])
            for frame, per_edge in enumerate(obs.forces.values, start=1):
                for edge, force in zip(obs.forces.edges, per_edge):
                    out.writerow([frame, edge, *map(repr, force.tolist())])
    files = [exp.domain.path] if isinstance(exp.domain, MeshDomain) else []
    for name in files + ([exp.mesh] if exp.mesh is not None else []):
        if bundle.root is None:
            break
        source, target = bundle.root / name, root / name
        if source.is_file() and source.resolve() != target.resolve():
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(source, target)
    return root


def write_displacements_csv(path: str | Path, ids, displacements) -> Path:
    """Write displacements in the bundle format (``frame,id,ux,uy[,uz]``; empty where NaN).

    Args:
        path: file to write.
        ids: ``(n,)`` int point ids.
        displacements: ``(n_frames, n, dim)`` float, length unit; frame k of the array is written as
            frame k + 1. Predicted displacements use the same format as measured ones.
    """
    ids = np.asarray(ids, dtype=np.int64)
    u = np.asarray(displacements, dtype=np.float64)
    if u.ndim != 3 or u.shape[1] != len(ids) or u.shape[2] not in (2, 3):
        raise ObservationError(f"displacements must have shape (n_frames, {len(ids)}, 2 or 3), got {u.shape}")
    path = Path(path)
    with open(path, "w", newline="", encoding="utf-8") as f:
        out = csv.writer(f, lineterminator="\n")
        out.writerow(["frame", "id", *(f"u{a}" for a in _AXES[: u.shape[2]])])
        for frame, rows in enumerate(u, start=1):
            for pid, row in zip(ids, rows):
                lost = np.isnan(row).any()
                out.writerow([frame, int(pid), *([""] * len(row) if lost else map(repr, row.tolist()))])
    return path


# ---------------------------------------------------------------------------------- readers
def _read_experiment(path: Path) -> Experiment:
    if not path.is_file():
        raise BundleError(path, "is missing; every bundle needs experiment.toml (see docs/measurement-bundle.md)")
    try:
        with open(path, "rb") as f:
            data = tomllib.load(f)
    except tomllib.TOMLDecodeError as e:
        raise BundleError(path, f"is not valid TOML: {e}") from None
    except UnicodeDecodeError as e:
        raise BundleError(path, f"is not UTF-8 text (byte {e.start}); save it as UTF-8") from None
    try:
        return Experiment.from_toml(data)
    except ExperimentError as e:
        raise BundleError(path, str(e)) from None


def _read_points(path: Path, dim: int):
    rows = _read_csv(path, ["id", *_AXES[:dim], "role"])
    ids, reference, roles, seen = [], [], [], {}
    for line, cells in rows:
        pid = _integer(cells[0], "id", path, line)
        if pid in seen:
            raise BundleError(path, f"point id {pid} is listed twice (lines {seen[pid]} and {line}); ids must be "
                                    "unique", line)
        seen[pid] = line
        role = cells[-1]
        if role not in ROLES:
            raise BundleError(path, f"unknown role {role!r} for point {pid}; use one of {list(ROLES)}", line)
        ids.append(pid)
        reference.append([_real(c, a, path, line) for c, a in zip(cells[1:-1], _AXES)])
        roles.append(role)
    if not ids:
        raise BundleError(path, "lists no points")
    return np.array(ids, np.int64), np.array(reference, np.float64), np.array(roles)


def _read_displacements(path: Path, ids: np.ndarray, dim: int) -> np.ndarray:
    names = [f"u{a}" for a in _AXES[:dim]]
    rows = _read_csv(path, ["frame", "id", *names])
    column = {int(pid): j for j, pid in enumerate(ids)}
    values, seen = {}, {}
    for line, cells in rows:
        frame = _frame(cells[0], path, line)
        pid = _integer(cells[1], "id", path, line)
        if pid not in column:
            raise BundleError(path, f"point id {pid} is not in points.csv; add it there or remove this row", line)
        if (frame, pid) in seen:
            raise BundleError(path, f"point {pid} has two rows in frame {frame} (lines {seen[frame, pid]} and {line})",
                              line)
        seen[frame, pid] = line
        empty = [c == "" for c in cells[2:]]
        if all(empty):
            values[frame, pid] = [math.nan] * dim
        elif any(empty):
            raise BundleError(path, f"point {pid} in frame {frame} has some of {','.join(names)} empty; leave all "
                                    "of them empty for a lost point, or give all of them", line)
        else:
            values[frame, pid] = [_real(c, n, path, line) for c, n in zip(cells[2:], names)]
    n_frames = _check_frames(path, sorted({f for f, _ in values}))
    for frame in range(1, n_frames + 1):
        for pid in column:
            if (frame, pid) not in values:
                raise BundleError(path, f"point {pid} has no row in frame {frame}; every point needs a row in every "
                                        f"frame (leave {','.join(names)} empty where it was lost)")
    u = np.empty((n_frames, len(ids), dim))
    for (frame, pid), v in values.items():
        u[frame - 1, column[pid]] = v
    return u


def _read_forces(path: Path, n_frames: int, dim: int, allowed_edges) -> Forces:
    names = [f"f{a}" for a in _AXES[:dim]]
    rows = _read_csv(path, ["frame", "edge", *names])
    values, seen = {}, {}
    for line, cells in rows:
        frame = _frame(cells[0], path, line)
        if frame > n_frames:
            raise BundleError(path, f"frame {frame} is not in displacements.csv (frames 1..{n_frames})", line)
        edge = cells[1]
        if not edge or (allowed_edges is not None and edge not in allowed_edges):
            raise BundleError(path, undefined_side(edge, allowed_edges), line)
        if (frame, edge) in seen:
            raise BundleError(path, f"edge {edge!r} has two rows in frame {frame} (lines {seen[frame, edge]} and "
                                    f"{line})", line)
        seen[frame, edge] = line
        values[frame, edge] = [_real(c, n, path, line) for c, n in zip(cells[2:], names)]
    edges = tuple(dict.fromkeys(e for _, e in values))
    if not edges:
        raise BundleError(path, "lists no forces; delete the file if no forces were measured")
    for edge in edges:
        for frame in range(1, n_frames + 1):
            if (frame, edge) not in values:
                raise BundleError(path, f"edge {edge!r} has no force in frame {frame}; give a force on every listed "
                                        "edge in every frame")
    return Forces(edges, np.array([[values[f, e] for e in edges] for f in range(1, n_frames + 1)]))


# ---------------------------------------------------------------------------------- cells
def _read_csv(path: Path, header: list[str]) -> list[tuple[int, list[str]]]:
    """Non-blank data rows as (line number, stripped cells), after checking the header."""
    if not path.is_file():
        raise BundleError(path, "is missing; every bundle needs points.csv and displacements.csv")
    rows = []
    with open(path, newline="", encoding="utf-8-sig") as f:
        reader = csv.reader(f)
        try:
            found = next(reader, None)
            if found is None or [c.strip() for c in found] != header:
                raise BundleError(path, f"header must be {','.join(header)} (the model's dimension decides x,y or "
                                        f"x,y,z), got {','.join(found or [])!r}", 1)
            for cells in reader:
                cells = [c.strip() for c in cells]
                if not any(cells):
                    continue
                if len(cells) != len(header):
                    raise BundleError(path, f"expected {len(header)} values ({','.join(header)}), got "
                                            f"{len(cells)}", reader.line_num)
                rows.append((reader.line_num, cells))
        except UnicodeDecodeError as e:
            raise BundleError(path, f"is not UTF-8 text (byte {e.start}); save it as UTF-8") from None
        except csv.Error as e:
            raise BundleError(path, f"is not valid CSV: {e}", reader.line_num) from None
    return rows


def _real(cell: str, name: str, path: Path, line: int) -> float:
    try:
        value = float(cell)
    except ValueError:
        raise BundleError(path, f"{name} = {cell!r} is not a number", line) from None
    if not math.isfinite(value):
        raise BundleError(path, f"{name} = {cell!r}: NaN or inf where a number is required (a lost point has "
                                "empty displacement cells)", line)
    return value


def _integer(cell: str, name: str, path: Path, line: int) -> int:
    try:
        value = int(cell)
    except ValueError:
        raise BundleError(path, f"{name} = {cell!r} is not an integer", line) from None
    if not -2**63 <= value < 2**63:
        raise BundleError(path, f"{name} = {cell!r} does not fit a 64-bit integer (|value| < 2**63)", line)
    return value


def _frame(cell: str, path: Path, line: int) -> int:
    frame = _integer(cell, "frame", path, line)
    if frame == 0:
        raise BundleError(path, "frame 0 is the reference configuration and is not listed; number frames from 1",
                          line)
    if frame < 0:
        raise BundleError(path, f"frame {frame} is negative; number frames 1, 2, 3, ...", line)
    return frame


def _check_frames(path: Path, frames: list[int]) -> int:
    if not frames:
        raise BundleError(path, "lists no frames; give at least frame 1")
    missing = sorted(set(range(1, frames[-1] + 1)) - set(frames))
    if missing:
        raise BundleError(path, f"frame {missing[0]} is missing (frames present: {frames[:10]}); frames are "
                                "numbered 1, 2, 3, ... without gaps")
    return frames[-1]
