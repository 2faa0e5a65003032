"""A region of other stiffness in a sheet (2D): an ellipse of its own modulus, started at a
candidate place and fitted with its centre, semi-axes, orientation and log modulus ratio
(:func:`refine.diagnosis.regions.fit_regions`), beside the regions the search found before it
(a second region is added to the first one's fit). A ``"place"`` cause; its fits name
``"stiffer-region"``, ``"softer-region"`` or ``"regions"``; a failed fit's row names ``"region"``.
Its job is named ``"ellipse"``."""

from __future__ import annotations

from refine.causes.registry import Cause, register
from refine.diagnosis.regions import fit_regions


def jobs(search, start) -> dict:
    """One fit at the candidate ``start`` (the search at it: ``search``,
    :class:`refine.diagnosis.search.AtCandidate`). The first region starts x3 or /3 at its
    candidate's outline; a later one starts where the last fit left the others, the new one at
    x1.5 or /1.5, so that the extended model starts close to the last one (a start at /3 could
    send a spurious second region's fit astray). No region is added to a hole (nothing where
    the model so far is one)."""
    used = search.used
    if used and search.best.cause == "hole":
        return {}
    shapes = [*(search.best.shapes if used else ()), search.shape((1.5 if used else 3.0) ** start.sign)]
    signs = [k.sign for k in (*used, start)]
    return {"ellipse": lambda: fit_regions(search.model, shapes, signs, search.fit, search.hold, search.sigma,
                                           restarts=())}


CAUSE = register(Cause("region", {2}, "place", ("region", "stiffer-region", "softer-region", "regions"), jobs,
                       doc="an elliptical region of other stiffness (added to the regions found before it)",
                       order=10))
