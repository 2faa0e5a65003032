"""A region of other stiffness in a solid (3D): an ellipsoidal inclusion
(:class:`refine.solid.inclusion.Inclusion`), started at a candidate region's moment ellipsoid and
fitted with its centre, semi-axes, orientation and log modulus ratio; it names
``"stiffer-region"`` or ``"softer-region"``."""

from __future__ import annotations

from refine.causes.registry import Cause, register
from refine.diagnosis.fitted import fit
from refine.solid.inclusion import Inclusion


def jobs(search, start) -> dict:
    """One fit: the ellipsoid started at the candidate ``start`` (a :class:`refine.solid.field.Blob`)."""
    return {"ellipsoid": lambda: fit(Inclusion.from_blob(search.model, start), search.fit, search.hold, search.sigma)}


CAUSE = register(Cause("ellipsoid", {3}, "place", ("stiffer-region", "softer-region"), jobs,
                       doc="an ellipsoidal region of other stiffness", order=10))
