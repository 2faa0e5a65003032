"""A diagnosis as ParaView time series: the initial and the refined model frame by frame, the
tracked points with the residuals of both, and the strain the points themselves show.

Written by :func:`refine.diagnosis.report.write` into ``DIR/paraview/``; see
:mod:`refine.model.paraview` for the fields of each series.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

import jaxfem as jf

from refine.diagnosis.measured_strain import equivalent, measured_strain
from refine.model.paraview import write_model_series, write_points_series


def write_series(d, folder: str | Path, U: dict | None = None) -> dict[str, Path]:
    """Write the diagnosis' series into ``folder``; returns their ``.pvd`` paths by name.

    - ``initial.pvd``, ``refined.pvd``: the initial and the refined (chosen) model per frame
      (:func:`refine.model.paraview.write_model_series`: displacement, Green-Lagrange strain,
      principal and equivalent strains, modulus, thickness, region tags; the refined model on its
      own mesh, e.g. quadratic triangles that follow a found region);
    - ``points.pvd``: the tracked points with ``predicted_initial``, ``residual_initial``,
      ``predicted_refined`` and ``residual_refined``
      (:func:`refine.model.paraview.write_points_series`);
    - ``measured_strain.pvd``: the Delaunay triangles of the tracked points with their measured
      ``green_lagrange_strain`` and ``equivalent_strain`` per triangle
      (:func:`refine.diagnosis.measured_strain.measured_strain`) and ``measured_displacement``.

    Args:
        d: the :class:`~refine.diagnosis.Diagnosis`.
        folder: where to write (created if missing).
        U: the models' equilibria from :func:`refine.diagnosis.figures.equilibria` (solved here
            if not given).
    """
    from refine.diagnosis.figures import equilibria

    U = U or equilibria(d)
    folder = Path(folder)
    obs = d.bundle.observations
    paths = {key: write_model_series(folder, key, fitted.model, fitted.theta, U[key])
             for key, fitted in (("initial", d.baseline), ("refined", d.chosen))}
    paths["points"] = write_points_series(folder, "points", obs, {"initial": d.baseline.predicted,
                                                                  "refined": d.chosen.predicted})
    paths["measured_strain"] = write_measured_strain_series(folder, "measured_strain", obs.reference,
                                                            obs.displacements)
    return paths


def write_measured_strain_series(folder: str | Path, name: str, points, displacements) -> Path:
    """Write the measured strain of ``points (n, 2)`` under ``displacements (frames, n, 2)``
    (length unit) as ``folder/name.pvd``, one VTU of triangles per frame."""
    folder = Path(folder)
    (folder / name).mkdir(parents=True, exist_ok=True)
    tri, E = measured_strain(points, displacements)
    mesh = jf.Mesh(np.asarray(points, float), tri, "tri3")
    files = []
    for f in range(len(displacements)):
        files.append(folder / name / f"frame_{f + 1:03d}.vtu")
        jf.write_vtu(files[-1], mesh, {"measured_displacement": displacements[f]},
                     {"green_lagrange_strain": E[f], "equivalent_strain": equivalent(E[f])})
    return jf.write_pvd(folder / f"{name}.pvd", files, times=range(1, len(files) + 1))
