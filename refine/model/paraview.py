"""A measured model and its points as ParaView time series (one VTU file per frame, one PVD).

:func:`write_model_series` writes a model's equilibrium in every frame on its mesh (linear or
quadratic triangles, which ParaView draws as VTK quadratic triangles): the nodal displacement,
and per cell the Green-Lagrange strain (3 x 3, 9 components), its in-plane principal values,
the equivalent strain, the modulus and the region tag. :func:`write_points_series` writes the
tracked points as a point cloud with their measured displacements and, for each model given, the
predicted displacements and the residuals (measured - predicted). Frame ``k`` (from 1) is step
``k`` of the series; frame 0, the reference configuration, is not written. Open the ``.pvd`` in
ParaView and use "Warp By Vector" on ``displacement`` to see the deformed shape.
"""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import jax
import jax.numpy as jnp
import numpy as np

import jaxfem as jf
from jaxfem.executables import Kept
from jaxfem.program import split

from refine.bundle.observations import Observations
from refine.bundle.roles import ROLES
from refine.model.measured import MeasuredModel


def model_fields(model: MeasuredModel, theta: dict, U) -> tuple[jf.Mesh, dict, dict]:
    """The mesh (at ``theta``'s node positions) and the point and cell data of equilibria.

    Args:
        model: the model.
        theta: its parameters (per-cell ``E``, nodes ``X``, ...), as :meth:`MeasuredModel.params`.
        U: displacements ``(n_frames, n_nodes, dim)``, length unit.

    Returns:
        ``(mesh, point_data, cell_data)``, each array with a leading frame axis:
        ``displacement (n_frames, n_nodes, dim)``; per cell ``green_lagrange_strain
        (n_frames, n_cells, 3, 3)``, ``principal_strain_1``, ``principal_strain_2`` (descending,
        dimensionless), ``equivalent_strain``, ``modulus`` (stress unit) and ``thickness`` (length
        unit, plane stress). Region tags go with the mesh. The strains are computed by one
        compiled function over all frames (JAX op by op would take seconds per frame).
    """
    mesh = model.mesh.with_nodes(np.asarray(theta["X"]))
    U = jnp.asarray(U)
    E, principal, eq = (np.asarray(a) for a in _strains(model.solver)(U, theta))
    n = len(U)
    cells = {"green_lagrange_strain": E,
             **{f"principal_strain_{k + 1}": principal[..., k] for k in range(principal.shape[-1])},
             "equivalent_strain": eq,
             "modulus": np.broadcast_to(np.asarray(theta["E"], float), (n, mesh.n_cells)),
             "thickness": np.broadcast_to(np.asarray(theta["thickness"], float), (n, mesh.n_cells))}
    return mesh, {"displacement": np.asarray(U)}, cells


#: one compiled strain function per solver program and dimension (the mesh's cells are an
#: argument; a figure and a series of the same frames share it), its executables kept on disk
#: (jaxfem.executables: a later process neither traces nor lowers it)
_COMPILED: dict = {}


def _strains(solver: jf.Solver):
    """``(U (frames, n_nodes, dim), theta) -> (E, principal, equivalent)`` per frame and cell, compiled."""
    prog, dim = solver.program, solver.problem.mesh.dim
    if (prog, dim) not in _COMPILED:
        def strains(U, th, cells):
            like = SimpleNamespace(_split=split, arrays={"cells": cells}, assembler=prog.asm, law=prog.asm.law,
                                   problem=SimpleNamespace(mesh=SimpleNamespace(dim=dim)))  # what jaxfem.postprocess reads

            def one(u):
                return (jf.green_lagrange_strain(like, u, th), jf.principal_strains(like, u, th),
                        jf.equivalent_strain(like, u, th))

            return jax.vmap(one)(U)

        _COMPILED[prog, dim] = Kept(strains, "paraview.strains")
    run = _COMPILED[prog, dim]
    return lambda U, theta: run(U, theta, solver.arrays["cells"])


def write_model_series(folder: str | Path, name: str, model: MeasuredModel, theta: dict, U) -> Path:
    """Write ``folder/name.pvd`` and ``folder/name/frame_NNN.vtu``, one file per frame.

    Args:
        folder: where to write (created if missing).
        name: the series' name (e.g. ``"model"``, ``"initial"``, ``"refined"``).
        model, theta: the model and its parameters (as :func:`model_fields`).
        U: the equilibrium displacements of every frame, ``(n_frames, n_nodes, dim)`` (e.g.
            :meth:`MeasuredModel.solve_frames`).

    Returns:
        The ``.pvd`` path.
    """
    folder = Path(folder)
    (folder / name).mkdir(parents=True, exist_ok=True)
    files = []
    mesh, point_data, cell_data = model_fields(model, theta, U)
    for f in range(len(point_data["displacement"])):
        files.append(folder / name / f"frame_{f + 1:03d}.vtu")
        jf.write_vtu(files[-1], mesh, {k: v[f] for k, v in point_data.items()}, {k: v[f] for k, v in cell_data.items()})
    return jf.write_pvd(folder / f"{name}.pvd", files, times=range(1, len(files) + 1))


def write_points_series(folder: str | Path, name: str, obs: Observations, predicted: dict) -> Path:
    """Write the tracked points, frame by frame, as ``folder/name.pvd`` and ``folder/name/*.vtu``.

    The points sit at their reference positions (warp by ``measured_displacement`` to see them
    move). Point data: ``id``; ``role`` (the index of the point's role in
    :data:`refine.bundle.roles.ROLES`: 0 boundary, 1 guide, 2 validate); ``tracked`` (0 where the
    point was lost in that frame, its values NaN); ``measured_displacement``; and for each
    ``key`` of ``predicted``: ``predicted_<key>`` and ``residual_<key>`` (measured - predicted,
    length unit).

    Args:
        folder: where to write (created if missing).
        name: the series' name (e.g. ``"points"``).
        obs: the observations.
        predicted: ``{key: (n_frames, n_points, dim)}`` predictions of each model at the points.

    Returns:
        The ``.pvd`` path.
    """
    folder = Path(folder)
    (folder / name).mkdir(parents=True, exist_ok=True)
    role = np.array([ROLES.index(r) for r in obs.roles], np.int32)
    files = []
    for f in range(obs.n_frames):
        measured = obs.displacements[f]
        data = {"id": np.asarray(obs.ids), "role": role, "tracked": obs.valid[f].astype(np.int32),
                "measured_displacement": measured}
        for key, pred in predicted.items():
            data[f"predicted_{key}"] = np.asarray(pred)[f]
            data[f"residual_{key}"] = measured - np.asarray(pred)[f]
        files.append(folder / name / f"frame_{f + 1:03d}.vtu")
        jf.write_points_vtu(files[-1], obs.reference, data)
    return jf.write_pvd(folder / f"{name}.pvd", files, times=range(1, obs.n_frames + 1))
