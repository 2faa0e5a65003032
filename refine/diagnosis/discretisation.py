"""The initial model's discretisation error, part of the null level the diagnosis compares its
misfit with (:mod:`refine.diagnosis.pipeline`, step 2): the change of its predictions when its
mesh is halved, found on a second, finer model solved beside the first (a mesh of another bucket
size: its programs compile and run beside the initial model's, :meth:`jaxfem.program.Program.lock_for`).

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


#: how much coarser the mesh of the chosen model's discretisation refit is
#: (:func:`refine.diagnosis.uncertainty.discretisation_bias`'s ``factor``)
COARSER = float(np.sqrt(2.0))


def warm_coarse(chosen, element: str, factor: float = COARSER) -> None:
    """Compile ahead the programs of the chosen hypothesis' refit on a mesh ``factor`` times
    coarser (the mesh's share of its error bars, :func:`~refine.diagnosis.uncertainty.discretisation_bias`):
    its model at ``chosen``'s shapes, meshed with ``element``, solved once with its Jacobian,
    so that the solve's programs for that mesh's bucket size (:mod:`jaxfem.padding`) compile
    while the chosen model is refitted, instead of after it. Speculative: nothing is kept but
    the compiled programs; a refit that ends elsewhere (another bucket, a hole) compiles its own,
    and a model that fails here is left to the refit to report."""
    from dataclasses import replace

    h = chosen.hypothesis
    if not getattr(chosen, "shapes", ()) or not h.remeshable:
        return
    try:
        compiled, z0 = replace(h.at(chosen.shapes, element), h=factor * chosen.model.h).build()
        compiled.evaluate(np.zeros(compiled.param.size) if z0 is None else z0)
    except Exception:  # noqa: BLE001 - speculative: the refit itself reports what fails
        return
