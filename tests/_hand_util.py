"""The coarse hand the hand tests share (no fingers, ~900 tet10 elements: one compile for the fast
tests; benchmarks/hand.py runs the paper-size and larger hands)."""

from __future__ import annotations

from dataclasses import replace

from examples.hand import PAPER, default_body, hand_mesh

COARSE = replace(PAPER, forearm=(48.0, 20.0, 28.0), palm=(48.0, 40.0, 26.0), wrist=(48.0, 16.0, 28.0), fingers=0,
                 thumb_phalanges=(20.0, 20.0), thumb=(20.0, 22.0), thumb_at=10.0)


def coarse_hand(h: float = 30.0):
    """The coarse hand meshed with tet10 elements no longer than ``h`` (mm), box faces closer than
    4.5 mm snapped to one grid plane (:func:`examples.hand.hand_mesh`)."""
    return hand_mesh(default_body(COARSE), h, 4.5)
