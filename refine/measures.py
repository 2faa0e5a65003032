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

from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from jaxtyping import Bool, Float

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
    can be differentiated and jitted with ``measured`` fixed). For residuals at a subset of the
    points, prepared once for many predictions, use :class:`Residuals`.

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
    return _weighted(predicted.reshape(-1)[index], meas.reshape(-1)[index], sigma), mask


def _weighted(predicted, measured, sigma):
    """(predicted - measured) / sigma: the one formula of a noise-weighted residual."""
    return (predicted - measured) / sigma


@dataclass(frozen=True, eq=False)
class Residuals:
    """Noise-weighted residuals of predicted against measured displacements at a set of points,
    over all frames, lost points removed: the residuals every least-squares fit and chi^2 in
    refine use (prepared once, applied to many predictions).

    Attributes:
        points: ``(n_points,)`` bool, the matched points among all the bundle's points.
        measured: ``(frames, m, dim)`` measured displacements at them, length unit (0 where lost).
        valid: ``(frames, m)`` bool, True where the point was tracked in that frame.
        sigma: noise standard deviation, length unit (the residuals are in its units).
    """

    points: Bool[np.ndarray, "n_points"]
    measured: Float[np.ndarray, "frames m dim"]
    valid: Bool[np.ndarray, "frames m"]
    sigma: float

    @classmethod
    def at(cls, displacements: Float[np.ndarray, "frames n_points dim"], points, sigma: float = 1.0) -> "Residuals":
        """The residuals at ``points`` (a bool mask over all points) of measured ``displacements``
        (NaN rows: lost), weighted by ``sigma``."""
        points = np.asarray(points, bool)
        meas = np.asarray(displacements)[:, points]
        return cls(points, np.nan_to_num(meas), np.isfinite(meas).all(axis=-1), float(sigma))

    @property
    def n(self) -> int:
        """Number of residuals: tracked (frame, point) pairs times the dimension."""
        return int(self.valid.sum()) * self.measured.shape[-1]

    def __call__(self, predicted) -> Float[Any, "n"]:
        """``(n,)`` residuals of predicted displacements of all points ``(frames, n_points, dim)``
        (numpy, or jax: the selection is static, so it can be jitted and differentiated)."""
        return _weighted(predicted[:, self.points], self.measured, self.sigma)[self.valid].reshape(-1)

    def chi2(self, predicted) -> float:
        """The sum of the squared residuals (chi^2, dimensionless)."""
        r = self(np.asarray(predicted))
        return float(r @ r)

    def difference(self, predicted) -> Float[np.ndarray, "frames m dim"]:
        """Predicted minus measured at the points, unweighted (anything where lost: see ``valid``)."""
        return predicted[:, self.points] - self.measured

    def weighted(self, values) -> Float[Any, "n"]:
        """Point values ``(frames, n_points, dim)`` weighted and selected like the residuals: their
        linear part (e.g. terms of a series of predicted displacements)."""
        return (values[:, self.points] / self.sigma)[self.valid].reshape(-1)

    def jacobian(self, jacobian: Float[np.ndarray, "frames n_points dim k"]) -> Float[np.ndarray, "n k"]:
        """The residuals' Jacobian from the prediction's ``(frames, n_points, dim, k)``."""
        return jacobian[:, self.points][self.valid].reshape(self.n, -1) / self.sigma


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
