"""Another homogeneous material law (2D and 3D): every law of jaxfem's registry that a diagnosis
tries instead of the initial model's (:data:`refine.diagnosis.laws.ALTERNATIVE_LAWS`, from
:func:`jaxfem.materials.alternatives`), each with its Poisson's ratio and its fitted extra
parameters (an anisotropic law's fibre angle from the best of a few starts) fitted
(:func:`refine.diagnosis.laws.fit_law`). A ``"global"`` cause: nothing placed; it names
``"material-law"``. Its jobs are named after the laws."""

from __future__ import annotations

from refine.causes.registry import Cause, register
from refine.diagnosis.laws import ALTERNATIVE_LAWS, fit_law


def applies(search) -> str | None:
    """Why no other law is tried: the settings say not (``try_laws``), or the initial law has no
    alternative in the registry."""
    if not getattr(search.cfg, "try_laws", True):
        return "other material laws are not tried (try_laws is off)"
    if not ALTERNATIVE_LAWS.get(search.model.experiment.law, ()):
        return f"the law {search.model.experiment.law!r} has no alternative in jaxfem's registry"
    return None


def jobs(search, start=None) -> dict:
    """One fit per alternative law of the initial model's (``start`` unused: nothing is placed)."""
    m = search.model
    return {law: (lambda law=law: fit_law(m, law, search.fit, search.hold, search.sigma))
            for law in ALTERNATIVE_LAWS.get(m.experiment.law, ())}


CAUSE = register(Cause("law", {2, 3}, "global", ("material-law",), jobs, applies,
                       doc="another homogeneous material law (each alternative of jaxfem's registry)", order=10))
