"""Another homogeneous material law, its Poisson's ratio (and any extra parameter) fitted."""

from __future__ import annotations

from refine.diagnosis.fitted import Fitted, fit_compiled, material_law
from refine.model.measured import MeasuredModel
from refine.model.objective import Compiled
from refine.model.parametrize import Combined, UniformParameter


ALTERNATIVE_LAWS = {"neo-hookean": ("mooney-rivlin", "saint-venant-kirchhoff"),
                    "mooney-rivlin": ("neo-hookean", "saint-venant-kirchhoff"),
                    "saint-venant-kirchhoff": ("neo-hookean", "mooney-rivlin"),
                    "linear-elastic": ("neo-hookean",)}


def fit_law(base: MeasuredModel, law: str, fit_mask, hold_mask, sigma) -> Fitted:
    """A different homogeneous material law, with its Poisson's ratio (and for Mooney-Rivlin its
    second-invariant share) fitted."""
    from dataclasses import replace

    ex = replace(base.experiment, law=law)
    model = MeasuredModel(ex, base.obs, mesh=base.mesh, h=base.h)
    parts = [UniformParameter("nu", float(ex.nu), 0.0, 0.499)]
    if law == "mooney-rivlin":
        parts.append(UniformParameter("c01_fraction", 0.25, 0.0, 0.95))
    param = Combined(tuple(parts))
    return fit_compiled(material_law(law), Compiled(model, param), fit_mask, hold_mask, sigma)
