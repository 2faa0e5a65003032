"""Another DIC code's results as :class:`Tracks`: DICe solution files and plain CSV exports.

A user with a DIC export reaches the same :class:`Tracks` a tracker gives, so everything after
tracking (bundles, diagnosis) is the same. Coordinates stay in the export's units (pixels for
DICe); nothing is dropped: a point that failed in a frame is kept, lost, with NaN position.
"""

from __future__ import annotations

import csv
import re
from pathlib import Path
from typing import Sequence

import numpy as np

from ._errors import TrackingError
from ._images import natural_key
from ._tracks import Tracks


class ExportError(TrackingError):
    """A DIC export cannot be read: missing columns, frames that disagree, non-numbers."""


DICE_REQUIRED = ("COORDINATE_X", "COORDINATE_Y", "DISPLACEMENT_X", "DISPLACEMENT_Y")
"""Columns every DICe solution file must have; optional: SUBSET_ID, SIGMA (-1: the subset
failed), MATCH (non-zero: not matched), STATUS_FLAG (kept in meta), GAMMA (match residual,
0 best: the tracks' quality is -GAMMA)."""


def regular_lattice(points: np.ndarray, tol: float = 1e-3):
    """The regular axis-aligned lattice ``(n, 2+)`` points lie on (a tracker's or a DIC code's
    step): ``(origin (2,) x/y, step (2,) x/y, index (n, 2) (row from y, column from x))``, or None
    where they lie on none (an axis with one value, or a point off a step by more than ``tol``
    of it)."""
    xy = np.asarray(points, dtype=np.float64)[:, :2]
    origin, step, index = [], [], []
    for axis in (0, 1):
        values = np.unique(np.round(xy[:, axis], 9))
        if values.size < 2:
            return None
        s = float(np.diff(values).min())
        k = (xy[:, axis] - values[0]) / s
        if not s > 0 or np.max(np.abs(k - np.rint(k))) > tol:
            return None
        origin.append(values[0])
        step.append(s)
        index.append(np.rint(k).astype(np.int64))
    return np.array(origin), np.array(step), np.stack(index[::-1], axis=1)


def lattice_index(reference: np.ndarray, tol: float = 1e-3) -> np.ndarray:
    """(n, 2) (row, column) of points that lie on a regular axis-aligned lattice (a DIC code's
    step, :func:`regular_lattice`), -1 everywhere if they do not or two share a site: the
    lattice's topology then gives the outline of the measured region, holes and notches
    included, as for a tracker's own lattice."""
    none = np.full((len(reference), 2), -1, dtype=np.int64)
    lattice = regular_lattice(reference, tol) if len(reference) >= 4 else None
    if lattice is None:
        return none
    out = lattice[2]
    return out if len({tuple(r) for r in out}) == len(out) else none


def _dice_files(sources) -> list[Path]:
    if isinstance(sources, (str, Path)):
        sources = [sources]
    files: list[Path] = []
    for source in sources:
        path = Path(source)
        if path.is_dir():
            found = sorted(path.glob("DICe_solution_*.txt"), key=natural_key)
            if not found:
                raise ExportError(f"folder {path} holds no DICe_solution_*.txt file")
            files.extend(found)
        elif path.is_file():
            files.append(path)
        else:
            raise ExportError(f"DICe solution file not found: {path}")
    return files


def _read_dice_table(path: Path) -> dict[str, np.ndarray]:
    """The columns of one DICe solution file (comment lines start with ``***``)."""
    with open(path, newline="") as fh:
        lines = [ln for ln in fh if ln.strip() and not ln.lstrip().startswith("*")]
    if not lines:
        raise ExportError(f"{path}: no header line (a DICe solution file has COORDINATE_X,COORDINATE_Y,...)")
    rows = list(csv.reader(lines))
    header = [h.strip().upper() for h in rows[0]]
    missing = [c for c in DICE_REQUIRED if c not in header]
    if missing:
        raise ExportError(f"{path}: missing column(s) {missing}; a DICe solution file needs {list(DICE_REQUIRED)}")
    try:
        values = np.array([[float(v) for v in r] for r in rows[1:]], dtype=np.float64).reshape(-1, len(header))
    except ValueError as error:
        raise ExportError(f"{path}: a value is not a number ({error})") from error
    return {name: values[:, k] for k, name in enumerate(header)}


def _dice_subset(path: Path) -> dict:
    """``{"subset_px": side}`` from a DICe solution file's header (``*** Subset size: 27``), or
    ``{}`` where it does not say (the subset is then unknown)."""
    with open(path) as fh:
        for line in fh:
            if not line.lstrip().startswith("*"):
                break
            m = re.match(r"\*+\s*subset size:\s*([0-9.]+)", line.strip(), re.IGNORECASE)
            if m:
                return {"subset_px": float(m.group(1))}
    return {}


def read_dice(sources: str | Path | Sequence[str | Path]) -> Tracks:
    """DICe solution files (one per deformed frame, against the same reference) as tracks in pixels.

    ``sources``: a folder (its ``DICe_solution_*.txt`` in natural order) or the files in frame
    order. Frame 0 of the tracks is the reference: positions = COORDINATE_X/Y; frame k: those plus
    DISPLACEMENT_X/Y of the k-th file. A subset is lost in a frame where DICe says it failed
    (SIGMA < 0, or MATCH not 0) or its displacement is not finite. Points are matched across files
    by SUBSET_ID where present, else by their coordinates (which must then agree).
    """
    files = _dice_files(sources)
    tables = [_read_dice_table(p) for p in files]
    first = tables[0]
    ref = np.c_[first["COORDINATE_X"], first["COORDINATE_Y"]]
    n = len(ref)
    ids = first["SUBSET_ID"].astype(np.int64) if "SUBSET_ID" in first else np.arange(n, dtype=np.int64)
    if len(np.unique(ids)) != n:
        raise ExportError(f"{files[0]}: SUBSET_ID repeats; each subset needs its own id")
    n_frames = len(tables) + 1
    positions = np.full((n_frames, n, 2), np.nan)
    positions[0] = ref
    lost = np.zeros((n_frames, n), bool)
    quality = np.zeros((n_frames, n))
    status = np.zeros((n_frames, n))
    for k, (path, t) in enumerate(zip(files, tables), start=1):
        if "SUBSET_ID" in t and "SUBSET_ID" in first:
            order = {int(i): j for j, i in enumerate(t["SUBSET_ID"])}
            try:
                rows = np.array([order[int(i)] for i in ids])
            except KeyError as error:
                raise ExportError(f"{path}: subset {error.args[0]} of {files[0]} is missing") from None
        else:
            if len(t["COORDINATE_X"]) != n or not np.allclose(np.c_[t["COORDINATE_X"], t["COORDINATE_Y"]], ref):
                raise ExportError(f"{path}: its subsets' coordinates differ from {files[0]}'s; "
                                  "give files of one DICe run (same reference and subsets)")
            rows = np.arange(n)
        u = np.c_[t["DISPLACEMENT_X"][rows], t["DISPLACEMENT_Y"][rows]]
        bad = ~np.isfinite(u).all(axis=1)
        if "SIGMA" in t:
            bad |= t["SIGMA"][rows] < 0
        if "MATCH" in t:
            bad |= t["MATCH"][rows] != 0
        lost[k] = bad
        positions[k] = np.where(bad[:, None], np.nan, ref + u)
        if "GAMMA" in t:
            quality[k] = -t["GAMMA"][rows]
        if "STATUS_FLAG" in t:
            status[k] = t["STATUS_FLAG"][rows]
    return Tracks(ids=ids, reference=ref, positions=positions, lost=lost, quality=quality,
                  grid_index=lattice_index(ref), units="px", quality_kind="-gamma (DICe, 0 best)",
                  meta={"source": "DICe", "files": [str(p) for p in files], "status_flag": status,
                        **_dice_subset(files[0])})


def write_dice(folder: str | Path, tracks: Tracks, start: int = 1) -> list[Path]:
    """Write tracks as DICe solution files ``DICe_solution_NN.txt`` (one per frame after the
    reference), with SUBSET_ID, COORDINATE_X/Y, DISPLACEMENT_X/Y, SIGMA (-1 where lost, else 0)
    and GAMMA (-quality); :func:`read_dice` reads them back equal. Returns the files written."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    u = tracks.displacements()
    width = max(2, len(str(tracks.n_frames - 1 + start - 1)))
    out = []
    for k in range(1, tracks.n_frames):
        path = folder / f"DICe_solution_{k + start - 1:0{width}d}.txt"
        with open(path, "w", newline="") as fh:
            fh.write("***\n*** written by tracking.write_dice (DICe solution format)\n***\n")
            w = csv.writer(fh, lineterminator="\n")
            w.writerow(["SUBSET_ID", "COORDINATE_X", "COORDINATE_Y", "DISPLACEMENT_X", "DISPLACEMENT_Y", "SIGMA",
                        "GAMMA"])
            for i in range(tracks.n_points):
                lost = bool(tracks.lost[k, i])
                ux, uy = (0.0, 0.0) if lost else u[k, i]
                w.writerow([int(tracks.ids[i]), repr(float(tracks.reference[i, 0])), repr(float(tracks.reference[i, 1])),
                            repr(float(ux)), repr(float(uy)), -1 if lost else 0, repr(float(-tracks.quality[k, i]))])
        out.append(path)
    return out


CSV_COLUMNS = ("x", "y", "ux", "uy")


def read_displacement_csv(sources: str | Path | Sequence[str | Path]) -> Tracks:
    """A plain CSV export as tracks, in the file's units.

    Either one file with columns ``frame,x,y,ux,uy`` (frames 1, 2, ...; ``x, y`` the reference
    position), or one file per frame (in the order given, or a folder's ``*.csv`` in natural
    order) with columns ``x,y,ux,uy``. An optional ``id`` column names the points; without it
    points are matched across frames by their reference position. Empty or non-finite ``ux, uy``:
    lost in that frame.
    """
    paths = [Path(s) for s in ([sources] if isinstance(sources, (str, Path)) else sources)]
    if len(paths) == 1 and paths[0].is_dir():
        paths = sorted(paths[0].glob("*.csv"), key=natural_key)
        if not paths:
            raise ExportError(f"folder {sources} holds no .csv file")
    frames: list[dict] = []
    for p in paths:
        if not p.is_file():
            raise ExportError(f"CSV file not found: {p}")
        with open(p, newline="") as fh:
            reader = csv.DictReader(fh)
            cols = [c.strip().lower() for c in (reader.fieldnames or [])]
            missing = [c for c in CSV_COLUMNS if c not in cols]
            if missing:
                raise ExportError(f"{p}: missing column(s) {missing}; a displacement CSV has "
                                  "[frame,]x,y,ux,uy[,id] (see docs/measurement-bundle.md)")
            rows = [{k.strip().lower(): (v or "").strip() for k, v in r.items()} for r in reader]
        if "frame" in cols:
            for f in sorted({int(r["frame"]) for r in rows}):
                frames.append({"path": p, "rows": [r for r in rows if int(r["frame"]) == f]})
        else:
            frames.append({"path": p, "rows": rows})
    if not frames:
        raise ExportError("no frames in the CSV export")

    def key(r):
        return r["id"] if "id" in r and r["id"] else (round(float(r["x"]), 9), round(float(r["y"]), 9))

    order: dict = {}
    ref = []
    for fr in frames:
        for r in fr["rows"]:
            k = key(r)
            if k not in order:
                order[k] = len(order)
                ref.append((float(r["x"]), float(r["y"])))
    n = len(order)
    ref = np.asarray(ref, dtype=np.float64)
    positions = np.full((len(frames) + 1, n, 2), np.nan)
    positions[0] = ref
    for f, fr in enumerate(frames, start=1):
        for r in fr["rows"]:
            try:
                u = (float(r["ux"]), float(r["uy"])) if r["ux"] and r["uy"] else (np.nan, np.nan)
            except ValueError as error:
                raise ExportError(f"{fr['path']}: {error}") from error
            positions[f, order[key(r)]] = ref[order[key(r)]] + np.asarray(u)
    lost = ~np.isfinite(positions).all(axis=-1)
    positions[lost] = np.nan
    keys = list(order)
    ids = (np.array([int(k) for k in keys], dtype=np.int64) if all(isinstance(k, str) for k in keys)
           else np.arange(n, dtype=np.int64))
    return Tracks(ids=ids, reference=ref, positions=positions, lost=lost, quality=np.zeros(lost.shape),
                  grid_index=lattice_index(ref), units="", quality_kind="none (CSV export)",
                  meta={"source": "csv", "files": [str(p) for p in paths]})
