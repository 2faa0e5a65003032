"""The default tracking model of the hand: the paper-size hand (``jaxfem.hand.PAPER`` at h = 24
mm, about the paper's 1,947 elements) with both thumb phalanges split along their length to
6 mm (2,682 tet10 elements, 4,683 nodes).

Why (benchmarks/results/hand.json, benchmarks/README.md's hand section): the thumb tip, flexed
towards the palm and seen from the back, is where the paper-size model's own discretisation error
(one element along the phalanx) put a tracked angle more than 1 degree off from the range clouds
(seed 1: 1.31 degrees); refined along the thumb, every seed's every angle stays within 1 degree
from the clouds, the markers and both once the sequence is smoothed (:func:`refine.hand.smooth`),
at about 11 % more elements and the same seconds per frame.

Units: mm.
"""

from __future__ import annotations

from jaxfem.hand import PAPER, HandModel, along, default_body, hand_mesh

#: the element length along the thumb's phalanges (mm) of the default tracking model
THUMB_H = 6.0


def tracking_model(thumb_h: float | None = THUMB_H, h: float = 24.0, snap: float = 4.5, dims=PAPER) -> HandModel:
    """The hand ``default_body(dims)`` meshed at ``h`` (mm; faces closer than ``snap`` mm on one grid
    plane) with both thumb phalanges split along their length (x) to at most ``thumb_h`` mm
    (``None``: not refined, the paper-size model), as a compiled :class:`jaxfem.hand.HandModel`."""
    body = default_body(dims)
    return HandModel(hand_mesh(body, h, snap, () if thumb_h is None else along(body, ("thumb_1", "thumb_2"), thumb_h, 0)))
