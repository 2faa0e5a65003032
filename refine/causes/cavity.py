"""An internal cavity in a solid (3D): an ellipsoid whose modulus is all but nothing, its log
ratio held at ``-MAX_LOG_RATIO`` (1/148 of the background's: a void to the surface's eye) and its
centre, semi-axes and orientation fitted (:class:`~refine.solid.inclusion_profile.RatioHeld` over
the inclusion's :class:`~refine.solid.inclusion.EllipsoidModulus`, nine unknowns). Tried only
from a softer candidate; it names ``"cavity"`` and reports its volume."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from refine.causes.registry import Cause, register
from refine.diagnosis.fitted import fit
from refine.model.objective import Compiled
from refine.solid.inclusion import MAX_LOG_RATIO, EllipsoidShape, Inclusion
from refine.solid.inclusion_profile import RatioHeld

CAVITY_LOG_RATIO = -MAX_LOG_RATIO
"""The log modulus ratio a cavity is modelled with."""


@dataclass(frozen=True)
class CavityShape(EllipsoidShape):
    """A fitted ellipsoidal cavity (its ``ratio`` the all but nothing it is modelled with)."""

    kind = "cavity"

    @property
    def cause(self) -> str:
        return "cavity"

    def describe(self) -> str:
        c, a = np.round(self.centre, 2).tolist(), np.round(self.axes, 2).tolist()
        return f"cavity at {c}, semi-axes {a}, volume {self.volume:.1f}"


@dataclass(frozen=True, eq=False)
class CavityModulus(RatioHeld):
    """The ellipsoid with its log ratio held at the cavity's; its shapes are :class:`CavityShape`."""

    def shape(self, z) -> CavityShape:
        s = self.base.shape(self.full(z, np))
        return CavityShape(s.centre, s.axes, s.rotation, s.ratio)

    def values(self, z) -> dict:
        s = self.shape(z)
        return {"cavity": {"centre": list(s.centre), "axes": list(s.axes), "volume": s.volume}}


@dataclass(frozen=True, eq=False)
class Cavity(Inclusion):
    """The hypothesis of one ellipsoidal cavity (the inclusion's geometry, its ratio held)."""

    def build(self):
        compiled, z0 = Inclusion.build(self)
        held = CavityModulus(compiled.param, float(CAVITY_LOG_RATIO), np.asarray(z0, float)[1:])
        return Compiled(self.model, held), np.asarray(held.z0)

    def cause_of(self, shapes) -> str:
        return "cavity" if shapes else "none"

    def on(self, model, shapes) -> Cavity:
        s = shapes[0]
        return Cavity(model, tuple(s.centre), tuple(s.axes), tuple(map(tuple, np.asarray(s.rotation))),
                      float(np.exp(CAVITY_LOG_RATIO)))


def jobs(search, start) -> dict:
    """One fit from a softer candidate ``start`` (a :class:`refine.solid.field.Blob`): the cavity
    at its moment ellipsoid shrunk by 0.8 (nothing from a stiffer one)."""
    if start.sign >= 0:
        return {}
    hyp = Inclusion.from_blob(search.model, start)
    cav = Cavity(search.model, hyp.centre, hyp.axes, hyp.rotation, float(np.exp(CAVITY_LOG_RATIO)))
    return {"cavity": lambda: fit(cav, search.fit, search.hold, search.sigma)}


CAUSE = register(Cause("cavity", {3}, "place", ("cavity",), jobs, doc="an internal ellipsoidal cavity", order=20))
