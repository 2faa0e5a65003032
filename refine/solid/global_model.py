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
from refine.bundle.roles import point_spacing
from refine.diagnosis.shapes import Hole
from refine.solid.cup import CupShape, bottom_points
from refine.solid.loaded import LoadedModel


def global_mesh(shape: CupShape, hole: Hole | None, h: float) -> jf.Mesh:
    """The whole cup holder (``tet10``, element size ``h``) with ``hole`` (cup frame) through its
    bottom, in the frame of the bundle's mesh."""
    e = None if hole is None else jf.Ellipse(*hole.centre, *hole.axes, hole.angle)
    mesh = jf.rimmed_wall(shape.r_in, shape.r_out, shape.bottom, shape.height, h, hole=e).mesh
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
    holds) left as boundary; the bottom's boundary points become ``guide`` points. A bundle seen
    from below only (no boundary point off the bottom: ``nonrigid track --range`` of the bottom)
    gets the fixture's hold instead: the rim held still (:func:`rim_fixture`)."""
    on = bottom_points(shape, obs.reference, tol)
    roles = np.where((obs.roles == "boundary") & on, "guide", obs.roles)
    if ((roles == "boundary").sum()) < 3:
        return rim_fixture(replace(obs, roles=roles), shape)
    return replace(obs, roles=roles)


def rim_fixture(obs: Observations, shape: CupShape) -> Observations:
    """``obs`` and the fixture's points (``boundary``, no motion in any frame, ids after the
    largest): three rings on the rim (z = height, mesh frame) at the point spacing of the bottom's
    points. The fixture holds the rim as the synthetic data's solve does (:mod:`examples.cup_holder.synthetic`)."""
    s = point_spacing(obs.reference)
    ring = []
    for r in shape.r_in + np.array([0.1, 0.5, 0.9]) * (shape.r_out - shape.r_in):
        t = np.linspace(0, 2 * np.pi, max(12, int(2 * np.pi * r / s)) + 1)[:-1]
        ring.append(np.c_[r * np.cos(t), r * np.sin(t), np.full(len(t), shape.height)])
    X = np.vstack(ring) + shape.offset
    n = len(X)
    ids = int(obs.ids.max(initial=0)) + 1 + np.arange(n)
    U = np.zeros((obs.n_frames, n, obs.dim))
    return Observations(np.r_[obs.ids, ids], np.vstack([obs.reference, X]), np.r_[obs.roles, np.full(n, "boundary")],
                        np.concatenate([obs.displacements, U], axis=1), forces=obs.forces)


def fixture_nodes(mesh: jf.Mesh, obs: Observations, tol: float) -> np.ndarray | None:
    """``(k,)`` the surface nodes the fixture's points drive: every node of the plane face
    (normal to the axis z) their ``boundary`` points lie on, each within ``tol`` (length unit; at
    least their depth noise, less than an element) of its plane (the rim; mesh and points in one
    frame). None where the boundary points do not share one such plane (then the model drives
    the nodes near them).

    Why: driven only near its points, the rim's nodes between the fixture's rings of points are
    free, so the global model's wall is softer than the clamped rim of the data and a hole fitted
    in it comes out too large."""
    z = obs.reference[obs.roles == "boundary", 2]
    if not len(z) or np.abs(z - np.median(z)).max() > tol:
        return None
    b = mesh.boundary_nodes()
    on = b[np.abs(mesh.nodes[b, 2] - np.median(z)) <= tol]
    return on if len(on) >= 3 else None


def global_check(bundle: Bundle, shape: CupShape, force, meshes: dict, tol: float,
                 linear_solver: str = "auto") -> dict:
    """Each global model of ``meshes`` (name -> mesh) held by the fixture's points and squeezed
    by ``force (n_frames, 3)``, predicting every point: the RMS error (length unit) of the
    ``validate`` points (all, the bottom's, the wall's) and its seconds."""
    obs = held_by_fixture(bundle.observations, shape, tol)
    on = bottom_points(shape, obs.reference, tol)
    validate = obs.roles == "validate"  # the fixture's points are boundary ones
    plane_tol = max(4 * (bundle.experiment.noise_std or 0.0), tol)
    out = {}
    for name, mesh in meshes.items():
        t0 = time.perf_counter()
        model = LoadedModel(bundle.experiment, obs, mesh, mesh.side_facets("back"), force,
                            linear_solver=linear_solver, driven=fixture_nodes(mesh, obs, plane_tol))
        pred = np.asarray(model.predict(model.params()))
        err = np.linalg.norm(pred - obs.displacements, axis=2)  # (frames, points)
        rms = lambda m: float(np.sqrt(np.nanmean(err[:, m] ** 2))) if m.any() else None  # noqa: E731
        out[name] = {"cells": int(mesh.n_cells), "validate_rms": rms(validate),
                     "bottom_rms": rms(validate & on), "wall_rms": rms(validate & ~on),
                     "seconds": time.perf_counter() - t0}
    return out
