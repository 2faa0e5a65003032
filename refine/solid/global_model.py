"""Local to global (the paper's Sec. 4): the local model's finding written into the global model
of the whole cup holder (a mesh with the hole and an experiment.toml that describes it, a bundle
`nonrigid simulate` and `nonrigid diagnose` read), and the global model's prediction of the whole
object checked against its held-out points.

The global model is held where the fixture holds the cup (the ``boundary`` points off the bottom
face: the rim) and squeezed by the measured force spread over its bottom face
(:class:`~refine.solid.loaded.LoadedModel`); it predicts every other point, the bottom's and the
wall's, from its geometry and the known modulus alone.
"""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

import numpy as np

import jaxfem as jf

from refine.bundle.experiment import MeshDomain
from refine.bundle.io import Bundle, write_bundle
from refine.bundle.observations import Observations
from refine.diagnosis.shapes import Hole
from refine.exceptions import ObservationError
from refine.solid.cup import CupShape, bottom_points
from refine.solid.loaded import LoadedModel


def global_mesh(shape: CupShape, hole: Hole | None, h: float) -> jf.Mesh:
    """The whole cup holder (``tet10``, element size ``h``) with ``hole`` (cup frame) through its
    bottom, in the frame of the bundle's mesh."""
    e = None if hole is None else jf.Ellipse(*hole.centre, *hole.axes, hole.angle)
    mesh = jf.cup_holder(shape.r_in, shape.r_out, shape.height, shape.bottom, h, hole=e).mesh
    return replace(mesh, nodes=mesh.nodes + shape.offset)


def finding_table(shape: CupShape, hole: Hole) -> dict:
    """experiment.toml's description of a found hole (``[meta.finding]``, mesh frame): an ellipse
    through the bottom, as report.json gives it."""
    c = np.add(hole.centre, shape.centre)
    return {"kind": "hole", "through": "bottom", "z": [shape.z0, shape.z0 + shape.bottom],
            "ellipse": {"centre": [float(c[0]), float(c[1])], "axes": [float(a) for a in hole.axes],
                        "angle": float(hole.angle)}}


def write_global(bundle: Bundle, shape: CupShape, hole: Hole | None, out: str | Path, h: float) -> Path:
    """Write the global model as a bundle in ``out``: ``mesh.vtu`` (the cup holder with ``hole``),
    experiment.toml (the bundle's, its domain that mesh, the finding in ``[meta.finding]``), the
    observations and forces. Returns the directory."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    jf.write_vtu(out / "mesh.vtu", global_mesh(shape, hole, h))
    ex = bundle.experiment
    extra = dict(ex.extra)
    if hole is not None:
        extra["meta"] = {**extra.get("meta", {}), "finding": finding_table(shape, hole)}
    ex = replace(ex, domain=MeshDomain("mesh.vtu"), mesh=None, extra=extra)
    return write_bundle(out, Bundle(ex, bundle.observations))


def held_by_fixture(obs: Observations, shape: CupShape, tol: float) -> Observations:
    """The observations with only the ``boundary`` points off the bottom face (those the fixture
    holds) left as boundary; the bottom's boundary points become ``guide`` points.

    Raises:
        ObservationError: fewer than 3 such points (nothing holds the global model)."""
    on = bottom_points(shape, obs.reference, tol)
    roles = np.where((obs.roles == "boundary") & on, "guide", obs.roles)
    if ((roles == "boundary").sum()) < 3:
        raise ObservationError("the global model needs at least 3 boundary points off the bottom face (where the "
                               "fixture holds the cup, e.g. its rim)")
    return replace(obs, roles=roles)


def global_check(bundle: Bundle, shape: CupShape, force, meshes: dict, tol: float,
                 linear_solver: str = "auto") -> dict:
    """Each global model of ``meshes`` (name -> mesh) held by the fixture's points and squeezed
    by ``force (n_frames, 3)``, predicting every point: the RMS error (length unit) of the
    ``validate`` points (all, the bottom's, the wall's) and its seconds."""
    obs = held_by_fixture(bundle.observations, shape, tol)
    on = bottom_points(shape, obs.reference, tol)
    validate = obs.roles == "validate"
    out = {}
    for name, mesh in meshes.items():
        t0 = time.perf_counter()
        model = LoadedModel(bundle.experiment, obs, mesh, mesh.side_facets("back"), force,
                            linear_solver=linear_solver)
        pred = np.asarray(model.predict(model.params()))
        err = np.linalg.norm(pred - obs.displacements, axis=2)  # (frames, points)
        rms = lambda m: float(np.sqrt(np.nanmean(err[:, m] ** 2))) if m.any() else None  # noqa: E731
        out[name] = {"cells": int(mesh.n_cells), "validate_rms": rms(validate),
                     "bottom_rms": rms(validate & on), "wall_rms": rms(validate & ~on),
                     "seconds": time.perf_counter() - t0}
    return out
