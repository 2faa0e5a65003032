"""The paper's error measures between predicted and measured point motion.

Every measure takes all frames at once: arrays ``(..., dim)`` of displacements (typically
``(n_frames, n, dim)``) from the reference configuration, in the length unit. A point lost in a
frame (NaN in ``measured``) is skipped; each measure returns an :class:`ErrorMeasure` that says
how many (frame, point) pairs it used. A NaN in ``predicted`` where the measurement is valid is an
error (a failed forward solve must not silently shrink the error).

Positions and displacements share the reference, so |q~ - q| = |u~ - u| and predictions may be
given either way for eq. (1); eq. (9) needs displacements (its denominator is |q - r| = |u|).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from refine.exceptions import ObservationError


class ErrorMeasure(NamedTuple):
    """A scalar error with its support.

    Attributes:
        value: the error, in the length unit (or dimensionless for :func:`tracking_error`); NaN
            when no pair was usable.
        n_used: number of (frame, point) pairs that entered it.
        n_skipped: pairs left out (lost in the measurement, or zero measured motion for eq. 9).
    """

    value: float
    n_used: int
    n_skipped: int


def displacement_error(predicted, measured) -> ErrorMeasure:
    """The paper's eq. (1): E = sum_j |q~_j - q_j| over guide points (and here over all frames).

    Args:
        predicted: ``(..., dim)`` predicted displacements (or positions), length unit.
        measured: same shape, measured; NaN rows are lost points and are skipped.

    Returns:
        Sum of Euclidean distances, length unit.
    """
    dist, skipped = _distances(predicted, measured)
    return ErrorMeasure(float(dist.sum()), dist.size, skipped)


def mean_position_error(predicted, measured) -> ErrorMeasure:
    """Mean distance between predicted and measured positions over valid pairs (report.json's
    ``guide_error`` / ``validation_error``), length unit. Shapes as :func:`displacement_error`."""
    dist, skipped = _distances(predicted, measured)
    return ErrorMeasure(float(dist.mean()) if dist.size else float("nan"), dist.size, skipped)


def tracking_error(predicted, measured, min_motion: float = 0.0) -> ErrorMeasure:
    """The paper's eq. (9): E_tracking = (1/n) sum_j |q_j - q~_j| / |q_j - r_j|.

    Each node's miss is divided by that node's own measured motion, then averaged (a mean of
    ratios, not a ratio of sums); here the mean runs over every valid (frame, validation point)
    pair. Dimensionless: 0.01 means predictions miss by 1 % of the motion.

    Args:
        predicted: ``(..., dim)`` predicted displacements u~ = q~ - r, length unit.
        measured: same shape, measured displacements u = q - r; NaN rows are lost and skipped.
        min_motion: pairs whose measured motion |u| is <= this (length unit) are skipped, since
            the ratio is undefined at zero motion; their number is in ``n_skipped``.
    """
    pred, meas, valid = _checked(predicted, measured)
    motion = np.linalg.norm(meas[valid], axis=-1)
    moving = motion > min_motion
    miss = np.linalg.norm(pred[valid] - meas[valid], axis=-1)[moving]
    n_used = int(moving.sum())
    value = float(np.mean(miss / motion[moving])) if n_used else float("nan")
    return ErrorMeasure(value, n_used, valid.size - n_used)


def residual_mask(measured) -> np.ndarray:
    """``(measured.size,)`` bool over the flattened components: True where the point is tracked.

    All components of a lost point are False together, so rows of a Jacobian of the flattened
    prediction, ``J[mask]``, line up with :func:`weighted_residuals`.
    """
    meas = np.asarray(measured, dtype=np.float64)
    valid = ~np.isnan(meas).any(axis=-1)
    return np.repeat(valid[..., None], meas.shape[-1], axis=-1).reshape(-1)


def weighted_residuals(predicted, measured, noise_std=None) -> tuple[Any, np.ndarray]:
    """Residuals r = (u~ - u) / sigma of every tracked component, flattened, for least squares.

    Works on numpy or jax arrays for ``predicted`` (the selection is a static integer index, so it
    can be differentiated and jitted with ``measured`` fixed).

    Args:
        predicted: ``(..., dim)`` predicted displacements, length unit (numpy or jax).
        measured: same shape, measured, numpy; NaN rows are lost points.
        noise_std: sigma, length unit: None (unweighted, sigma = 1), a scalar, or an array that
            broadcasts to ``measured.shape`` (e.g. per point or per component).

    Returns:
        ``(r, mask)``: r ``(n_valid_components,)`` dimensionless when sigma is given; mask
        ``(measured.size,)`` bool from :func:`residual_mask`.
    """
    meas = np.asarray(measured, dtype=np.float64)
    if tuple(predicted.shape) != meas.shape:
        raise ObservationError(f"predicted has shape {tuple(predicted.shape)} but measured has {meas.shape}")
    mask = residual_mask(meas)
    index = np.flatnonzero(mask)
    sigma = 1.0
    if noise_std is not None:
        full = np.broadcast_to(np.asarray(noise_std, np.float64), meas.shape)
        if not np.all(np.isfinite(full) & (full > 0)):
            raise ObservationError(f"noise_std must be positive and finite, got {noise_std!r}")
        sigma = full.reshape(-1)[index]
    return (predicted.reshape(-1)[index] - meas.reshape(-1)[index]) / sigma, mask


def misfit(residuals):
    """Least-squares objective 0.5 * sum r^2 (numpy or jax; a 0-d array for jax input)."""
    return 0.5 * (residuals * residuals).sum()


def _checked(predicted, measured):
    pred = np.asarray(predicted, dtype=np.float64)
    meas = np.asarray(measured, dtype=np.float64)
    if pred.shape != meas.shape or meas.ndim < 1:
        raise ObservationError(f"predicted has shape {pred.shape} but measured has {meas.shape}")
    valid = ~np.isnan(meas).any(axis=-1)
    if not np.all(np.isfinite(pred[valid])):
        raise ObservationError(
            "predicted displacements contain NaN or inf where the point was measured; check the forward solve"
        )
    return pred, meas, valid


def _distances(predicted, measured) -> tuple[np.ndarray, int]:
    pred, meas, valid = _checked(predicted, measured)
    return np.linalg.norm(pred[valid] - meas[valid], axis=-1), int((~valid).sum())
