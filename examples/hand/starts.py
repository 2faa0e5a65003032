"""Where the hand tracker starts a frame's fit: the constant-velocity prediction from the last two
fits (the first start of every frame that has two fits before it), and, when a fit ends at a high
robust cost (a joint lost to another local minimum), the other starts tried in turn: the last fit
itself (where the first start was the prediction), then the last fit with one angle moved by each
offset.

A start is ``q (6 + n_angles,)``: the global pose (rotation vector, radians; translation, mm) then
the joint angles (radians), in the tracker's order.
"""

from __future__ import annotations

import numpy as np


def fit_vector(fit, n_angles: int) -> np.ndarray:
    """``q (6 + n_angles,)`` of a :class:`~examples.hand.FrameFit` (``None``: the rest, identity pose)."""
    return np.zeros(6 + n_angles) if fit is None else np.r_[fit.pose, fit.angles]


def predicted(start, before) -> np.ndarray | None:
    """The constant-velocity prediction ``2 q_start - q_before`` of the pose and the angles from the
    last two fits (:class:`~examples.hand.FrameFit`), ``None`` without both."""
    if start is None or before is None:
        return None
    n = len(start.angles)
    return 2 * fit_vector(start, n) - fit_vector(before, n)


def restart_starts(last: np.ndarray, names, angles, offsets, include_last: bool):
    """The other starts ``(6 + n_angles,)``, in the order tried: ``last`` (the last fit's ``q``)
    itself where ``include_last`` (the first start was the prediction), then ``last`` with one of
    ``angles`` (names among ``names``; ``None``: every one) moved by each of ``offsets`` (radians),
    the pose kept."""
    if include_last:
        yield last.copy()
    for name in angles or names:
        for d in offsets:
            q = last.copy()
            q[6 + list(names).index(name)] += d
            yield q
