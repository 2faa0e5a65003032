"""The default tracking model of the hand: the paper-size hand (``jaxfem.hand.PAPER`` at h = 24
mm, about the paper's 1,947 elements) with both thumb phalanges split along their length to
6 mm (2,682 tet10 elements, 4,683 nodes).

Why (benchmarks/results/hand.json, benchmarks/README.md's hand section): the thumb tip, flexed
towards the palm and seen from the back, is where the paper-size model's own discretisation error
(one element along the phalanx) leaves a tracked angle more than 1 degree off from the range
clouds (seed 1: 1.31 degrees per frame, 1.14 with the sequence smoothed by
:func:`refine.hand.smooth`); refined along the thumb, every angle of every frame of seeds 0-2
stays within 1 degree from the clouds (0.83 at most, smoothed) and from the clouds with the
markers (0.43), at 11 % more elements. From the 13 markers alone seed 2's thumb tip ends 1.22
degrees off (smoothed) with this model and 0.996 with the paper-size one: the markers' noise (two
markers on the 25 mm tip phalanx, 0.1 mm: noise-free markers leave 0.23 degrees at most, fresh
noise draws 0.47-0.86, and about one sequence in six ends some angle beyond 1 degree from a
correct fit), not the model, so the model that fails from the data it cannot change (the clouds'
floor) is the one set aside.

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
