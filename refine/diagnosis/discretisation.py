"""The initial model's discretisation error, part of the null level the diagnosis compares its
misfit with (:mod:`refine.diagnosis.pipeline`, step 2): the change of its predictions when its
mesh is halved, found on a second, finer model set up in the diagnosis's threads beside the
first (their solves take the shared program's lock in turn, :mod:`jaxfem.program`).

The chosen model's discretisation error (its mesh and its drive) is
:func:`refine.diagnosis.uncertainty.with_discretisation`'s.
"""

from __future__ import annotations

import numpy as np
from jaxtyping import Bool

from refine.model.measured import MeasuredModel


def discretisation_floor(model: MeasuredModel, guide: Bool[np.ndarray, "n_points"]) -> float:
    """Std (length unit) of the initial ``model``'s discretisation error at the ``guide`` points:
    the change of its predictions when the mesh is halved, scaled by 4/3 (second-order
    Richardson); NaN where a model cannot be solved (the diagnosis then stops with the solver's
    message)."""
    fine = MeasuredModel(model.experiment, model.obs, h=0.5 * model.h, linear_solver=model.linear_solver)
    d = np.asarray(fine.predict(fine.params())) - np.asarray(model.predict(model.params()))
    d = d[:, guide]
    if not np.isfinite(d).all():
        return float("nan")
    return float(4.0 / 3.0 * np.sqrt(np.mean(d**2)))

