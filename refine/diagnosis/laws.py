"""Another homogeneous material law, its Poisson's ratio (and any extra parameter) fitted."""

from __future__ import annotations

from jaxfem.materials import LAWS, alternatives, get_material

from refine.diagnosis.fitted import Fitted, fit_compiled, material_law
from refine.model.measured import MeasuredModel
from refine.model.objective import Compiled
from refine.model.parametrize import Combined, UniformParameter

#: law -> the laws a diagnosis tries instead, in order (derived from jaxfem's registry:
#: :func:`jaxfem.materials.alternatives`)
ALTERNATIVE_LAWS = {law: alternatives(law) for law in LAWS}


def fit_law(base: MeasuredModel, law: str, fit_mask, hold_mask, sigma) -> Fitted:
    """A different homogeneous material law, with its Poisson's ratio and the law's extra
    parameters (its :attr:`jaxfem.Material.extra`, from their defaults within their bounds) fitted."""
    from dataclasses import replace

    ex = replace(base.experiment, law=law, parameters={})  # the initial law's extra parameters are not this law's
    model = MeasuredModel(ex, base.obs, mesh=base.mesh, h=base.h, linear_solver=base.linear_solver)
    parts = [UniformParameter("nu", float(ex.nu), 0.0, 0.499)]
    parts += [UniformParameter(q.name, q.default, q.lower, q.upper) for q in get_material(law).extra]
    param = Combined(tuple(parts))
    return fit_compiled(material_law(law), Compiled(model, param), fit_mask, hold_mask, sigma)
