"""The hand tracker's records: :class:`TrackConfig` (how each frame is fitted, as data) and
:class:`FrameFit` (what one frame's fit gives). Split from :mod:`examples.hand.track`, which
re-exports both.

Units: mm, radians.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class TrackConfig:
    """Settings of the hand tracker (data).

    Attributes:
        noise: a cloud point's depth noise (mm, standard deviation); marker_noise: a marker's (mm).
        robust: Cauchy scale of a residual, in noise units.
        candidates: triangles each point is measured against (its nearest by centroid).
        max_points: cloud points used per frame (a random subset of the rest; padded to this, so
            one compiled residual serves every frame).
        iterations: most Levenberg-Marquardt trials per frame; step_tol: stop when no angle
            moves more than this (radians) and the pose less than this (radians, and mm x 0.01).
        far: refuse a cloud whose median distance to the hand at the starting estimate exceeds
            this (mm): it is in another frame or unit, or not of this hand.
        max_turn: the largest change of any angle in one trial (radians; a longer step is
            shortened): a trust region against jumps to another local minimum.
        pose: fit the global pose (otherwise it stays where it starts).
        seed: seeds the subset of points.
        predict: start each frame that has two fits before it from their constant-velocity
            prediction (pose and angles), else from the last fit (a prediction the model cannot
            solve falls back to the last fit).
        restart_cost: when a frame's fit ends with a robust cost above this per used residual (noise
            units squared; pure noise gives about 0.9, a lost joint tens), other starts are tried in
            turn (``inf``: never; 0: all of them): the last fit (where the first start was the
            prediction), then per angle in ``restart_angles`` (default: every fitted angle) the last
            fit's angles with that one moved by each of ``restart_offsets`` (radians); each start gets
            ``restart_trials`` Levenberg-Marquardt trials, one that ends below the best cost so far is
            carried on to convergence and becomes the best, and the search stops at the first such
            fit whose cost is at most ``restart_cost`` per residual.
    """

    noise: float = 0.2
    marker_noise: float = 0.1
    robust: float = 3.0
    candidates: int = 12
    max_points: int = 1500
    iterations: int = 12
    step_tol: float = 1e-4
    far: float = 20.0
    max_turn: float = 0.15
    pose: bool = True
    seed: int = 0
    predict: bool = True
    restart_cost: float = 4.0
    restart_angles: tuple[str, ...] | None = None
    restart_offsets: tuple[float, ...] = (0.2, -0.2)
    restart_trials: int = 3


@dataclass(frozen=True)
class FrameFit:
    """One frame's fit: ``angles (n_angles,)`` radians (the tracker's ``names``), ``pose (6,)``,
    the model's displacement ``u (n_nodes, 3)`` mm (model frame), ``rms``: RMS point-to-surface
    distance of the cloud's inliers (mm; NaN without a cloud), ``marker_rms`` (mm; NaN without
    markers), ``iterations`` (trials, restarts' included), ``seconds``, ``cost`` (the robust cost at
    the fit, noise units squared), ``restarted``: whether other starts were tried (and ``restart``:
    which start won, -1 the first fit; :func:`examples.hand.starts.restart_starts`' order),
    ``predicted``: whether the first start was the constant-velocity prediction."""

    angles: np.ndarray
    pose: np.ndarray
    u: np.ndarray
    rms: float
    marker_rms: float
    iterations: int
    seconds: float
    cost: float = float("nan")
    restarted: bool = False
    restart: int = -1
    predicted: bool = False
