"""A hole in a material of another law (2D): the best hole fitted so far refitted in the
alternative law that fitted best alone, the hole's geometry and the law's parameters together
(:func:`refine.diagnosis.hole_law.hole_law_jobs`; job ``"hole with LAW"``). A ``"global"``
cause after the other laws (``"law"``), whose fits it reads; it names ``"hole"``."""

from __future__ import annotations

from refine.causes.registry import Cause, register
from refine.diagnosis.hole_law import hole_law_jobs


def applies(search) -> str | None:
    """Why not: the settings say other laws are not tried (``try_laws``)."""
    return None if getattr(search.cfg, "try_laws", True) else "other material laws are not tried (try_laws is off)"


def jobs(search, start=None) -> dict:
    """The hole in the best law, where both a hole and another law were fitted (``search.fitted``)."""
    return hole_law_jobs(search.model, search.fitted, search.fit, search.hold, search.sigma)


CAUSE = register(Cause("hole-in-law", {2}, "global", ("hole",), jobs, applies,
                       doc="a hole in a material of the alternative law that fitted best", order=20))
