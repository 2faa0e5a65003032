"""``nonrigid import --dvc``: a solid bundle from a digital volume correlation (DVC) export,
points inside the body.

A DVC code correlates subvolumes of volume images (CT, MRI) and reports, at each subvolume's centre,
its reference position and displacement. :func:`read_dvc_csv` reads one CSV with the columns
``x, y, z, ux, uy, uz`` (header names in any case; an optional ``frame`` column, one frame without
it; other columns, e.g. a correlation score, are ignored). :func:`bundle_from_dvc` makes a solid
bundle of them on the body's mesh: every point must lie in the mesh; the points on the named
boundary faces drive the model (``boundary``), the others are compared where they are, inside the
volume (``guide``, or ``validate`` for a seeded share).
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from refine.bundle.experiment import Experiment, MeshDomain
from refine.bundle.io import Bundle
from refine.bundle.observations import Observations
from refine.exceptions import ObservationError

COLUMNS = ("x", "y", "z", "ux", "uy", "uz")


def read_dvc_csv(path: str | Path, scale: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """The points of a DVC export: reference positions ``(n, 3)`` and displacements ``(frames, n, 3)``.

    Args:
        path: the CSV file (columns :data:`COLUMNS`, optional ``frame``; see the module).
        scale: length units (mm) per unit of the file, applied to positions and displacements.

    With a ``frame`` column, frames are taken in increasing order of its values and points are
    matched across them by their reference position ``x, y, z`` (the same numbers); a point missing from a
    frame, or with an empty or non-finite displacement there, is lost in it (NaN).

    Raises:
        ObservationError: a missing column, a non-numeric position or frame, a point listed twice
            in a frame, or no rows.
    """
    path = Path(path)
    if not path.is_file():
        raise ObservationError(f"DVC file not found: {path}")
    if not (isinstance(scale, (int, float)) and math.isfinite(scale) and scale > 0):
        raise ObservationError(f"the scale must be a positive number (mm per unit of the export), got {scale!r}")
    with open(path, newline="", encoding="utf-8-sig") as fh:
        reader = csv.DictReader(fh)
        cols = [(c or "").strip().lower() for c in (reader.fieldnames or [])]
        missing = [c for c in COLUMNS if c not in cols]
        if missing:
            raise ObservationError(f"{path}: missing column(s) {missing}; a DVC export needs x,y,z,ux,uy,uz "
                                   f"(and optionally frame), found {cols}")
        rows = [{(k or "").strip().lower(): (v or "").strip() for k, v in r.items()} for r in reader]
    if not rows:
        raise ObservationError(f"{path}: no data rows")
    frames = [_number(r.get("frame", "1"), path, i, "frame") for i, r in enumerate(rows)]
    if not all(f == int(f) for f in frames):
        raise ObservationError(f"{path}: the frame column must hold whole numbers")
    keys, index, point = [], {}, []
    for i, r in enumerate(rows):
        key = tuple(_number(r[c], path, i, c) for c in COLUMNS[:3])
        if key not in index:
            index[key] = len(keys)
            keys.append(key)
        point.append(index[key])
    order = sorted(set(frames))
    U = np.full((len(order), len(keys), 3), np.nan)
    seen = np.zeros(U.shape[:2], bool)
    for i, (r, f, p) in enumerate(zip(rows, frames, point)):
        k = order.index(f)
        if seen[k, p]:
            raise ObservationError(f"{path}: the point at {list(keys[p])} is listed twice in frame {int(f)} "
                                   f"(row {i + 2})")
        seen[k, p] = True
        U[k, p] = [_number(r[c], path, i, c, empty=np.nan) for c in COLUMNS[3:]]
    U[~np.isfinite(U).all(axis=2)] = np.nan
    return np.asarray(keys, np.float64) * scale, U * scale


def _number(text: str, path, row: int, column: str, empty=None) -> float:
    if text == "" and empty is not None:
        return empty
    try:
        value = float(text)
    except ValueError:
        raise ObservationError(f"{path}: row {row + 2}, column {column}: {text!r} is not a number") from None
    if empty is None and not math.isfinite(value):
        raise ObservationError(f"{path}: row {row + 2}, column {column} is {text}; positions must be finite")
    return value


def bundle_from_dvc(reference, displacements, mesh_path: str | Path, name: str, model, faces=None,
                    tolerance: float | None = None, validate_fraction: float = 0.2, seed: int = 0) -> Bundle:
    """A solid bundle of DVC points on the mesh ``mesh_path`` (not written; see
    :func:`refine.bundle.io.write_bundle`, which copies the mesh into it).

    Args:
        reference: ``(n, 3)`` positions in the mesh's axes and length unit; displacements:
            ``(frames, n, 3)`` (NaN: lost).
        mesh_path: the body's 3D mesh (any meshio format).
        name: the experiment's name; model: a :class:`refine.bundle.from_tracks.ModelSkeleton`
            (law, E, nu, noise_std; the kind is ``"solid"``).
        faces: the faces whose points become ``boundary``: named faces of the mesh or sides of its
            bounding box (``left`` ... ``front``); None: every face the mesh names. Those holding
            points are written as ``domain.boundary_faces``: the model checks the boundary points
            against them and drives every node of them.
        tolerance: how far from a face a point may lie and count as on it, and how far outside the
            mesh any point may lie (length unit); None: a quarter of the points' spacing, as the
            model allows (:func:`refine.model.boundary.outline_tolerance`).
        validate_fraction: the share of the other points held out (``validate``), drawn under ``seed``.

    Raises:
        ObservationError: points outside the mesh (how many, and the farthest), fewer than 3 points
            on the faces, a mesh that names no faces and no ``faces`` given, or bad shapes.
    """
    import jaxfem as jf
    from jaxfem.probe import find_cells
    from jaxfem.surface import project_to_surface

    from refine.bundle.roles import point_spacing
    from refine.model.boundary import face_distance, outline_tolerance

    X = np.asarray(reference, np.float64)
    U = np.asarray(displacements, np.float64)
    if X.ndim != 2 or X.shape[1] != 3 or len(X) < 4 or U.shape != (len(U), len(X), 3) or len(U) < 1:
        raise ObservationError(f"DVC points must be (n >= 4, 3) with displacements (frames, n, 3), got {X.shape} "
                               f"and {U.shape}")
    if not 0.0 <= validate_fraction <= 1.0:
        raise ObservationError(f"validate_fraction must be in [0, 1], got {validate_fraction}")
    mesh_path = Path(mesh_path)
    mesh = jf.read_mesh(mesh_path)
    if mesh.dim != 3:
        raise ObservationError(f"{mesh_path} is a {mesh.dim}D mesh; DVC points need the body's 3D mesh")
    tol = outline_tolerance(point_spacing(X), model.noise_std) if tolerance is None else float(tolerance)
    outside = find_cells(mesh, X)[2] > 1e-9
    off = np.zeros(len(X))
    off[outside] = project_to_surface(mesh, X[outside])[1]
    if (off > tol).any():
        worst = int(np.argmax(off))
        raise ObservationError(
            f"{int((off > tol).sum())} of {len(X)} DVC points lie outside the mesh {mesh_path.name}: the farthest, "
            f"point {worst + 1} at {X[worst].round(6).tolist()} (ids follow the file's order), is {off[worst]:.3g} "
            f"from its surface "
            f"(allowed: {tol:.3g}). Check that the points and the mesh share their axes and units (--scale)")
    if faces is None:
        faces = tuple(mesh.faces)
        if not faces:
            raise ObservationError(f"{mesh_path.name} names no faces (gmsh physical groups of boundary facets): give "
                                   "the faces the boundary points lie on, e.g. --boundary-faces left,right (the "
                                   "bounding box's sides)")
    domain = MeshDomain(mesh_path.name, boundary_faces=tuple(faces))
    near = face_distance(mesh, domain, domain.boundary_faces, X) <= tol  # (faces, points)
    on = near.any(axis=0)
    if on.sum() < 3:
        raise ObservationError(
            f"only {int(on.sum())} DVC points lie on the faces {list(domain.boundary_faces)} (within {tol:.3g}); at "
            "least 3 are needed to drive the model. A DVC code's subvolumes keep clear of the surface: add surface "
            "points (e.g. stereo DIC), name other faces, or widen the tolerance (--face-tolerance)")
    # the faces that hold points: the model drives every node of its boundary faces
    domain = MeshDomain(mesh_path.name, boundary_faces=tuple(f for f, hit in zip(faces, near.any(axis=1)) if hit))
    roles = np.where(on, "boundary", "guide").astype("<U8")
    interior = np.flatnonzero(~on)
    held = np.random.default_rng(seed).choice(interior, size=int(round(validate_fraction * len(interior))),
                                              replace=False)
    roles[held] = "validate"
    obs = Observations(ids=np.arange(1, len(X) + 1), reference=X, roles=roles, displacements=U)
    exp = Experiment(name=name, kind="solid", domain=domain, law=model.law, E=model.E, nu=model.nu,
                     units={"length": "mm"}, noise_std=model.noise_std)
    return Bundle(exp, obs, root=mesh_path.parent)


def import_dvc(path: str | Path, mesh: str | Path, out: str | Path, *, scale: float = 1.0, faces=None,
               tolerance: float | None = None, name: str | None = None, model=None, validate_fraction: float = 0.2,
               seed: int = 0, quiet: bool = False) -> Bundle:
    """Read a DVC export and write it as a solid bundle on ``mesh`` (what ``nonrigid import --dvc``
    does; the arguments as for :func:`read_dvc_csv` and :func:`bundle_from_dvc`).

    Returns:
        The bundle as read back from ``out``.
    """
    import jaxfem as jf

    from refine.bundle.from_tracks import ModelSkeleton
    from refine.bundle.io import read_bundle, write_bundle
    from refine.bundle.roles import ROLES

    out, mesh = Path(out), Path(mesh)
    if not mesh.is_file():
        raise ObservationError(f"mesh file not found: {mesh}")
    X, U = read_dvc_csv(path, scale)
    try:
        bundle = bundle_from_dvc(X, U, mesh, name or out.resolve().name, model or ModelSkeleton(), faces, tolerance,
                                 validate_fraction, seed)
    except jf.MeshError as e:
        raise ObservationError(f"{mesh}: {e}") from None
    write_bundle(out, bundle)
    toml = out / "experiment.toml"
    toml.write_text(f"# written by `nonrigid import --dvc` from {Path(path).name} on {mesh.name}; coordinates in mm = "
                    f"the export's x {scale:.6g}\n# CHECK: the [model] and [material] sections are a starting point, "
                    "not measured.\n\n" + toml.read_text(encoding="utf-8"), encoding="utf-8")
    if not quiet:
        roles = bundle.observations.roles
        print(f"imported {len(X)} DVC points x {len(U)} frames: "
              + ", ".join(f"{int((roles == r).sum())} {r}" for r in ROLES)
              + f"; boundary on {list(bundle.experiment.domain.boundary_faces)}")
        bare = [f for f in (faces or ()) if f not in bundle.experiment.domain.boundary_faces]
        if bare:
            print(f"  no points on {bare}: left free")
        print(f"wrote {out}; check the [model] and [material] sections of experiment.toml before `nonrigid diagnose`")
    return read_bundle(out)
