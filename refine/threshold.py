"""The threshold of a strain curve: where the growth rate of the maximum strain changes as a
motion (or load) goes on, with its uncertainty (the paper's Sec. 5: at 80-90 % of the total motion).

The curve is fitted by two straight segments that meet at the threshold (a continuous
"hinge": ``s = a + b x + c max(x - x0, 0)``). For a fixed ``x0`` the fit is linear least squares,
so the residual sum of squares ``RSS(x0)`` is profiled over ``x0`` on a fine grid between the
second and the second-last sample (each segment holds at least two samples) and refined by a
bounded scalar search. The uncertainty of ``x0`` is its profile-likelihood interval,
``{x0 : (RSS(x0) - RSS_min) / s^2 <= F(level; 1, n - 4)}`` with ``s^2 = RSS_min / (n - 4)``
(the F form of the likelihood ratio with the noise estimated from the residuals, Muggeo 2003's
recommendation for a breakpoint, whose Wald error is unreliable because RSS is not smooth in x0
where x0 crosses a sample). Whether there is a change at all is the F test of the hinge
against one straight line (``p_value``). With ``rising=True`` only a change to FASTER growth counts
(``c >= 0``, the paper's threshold past which the skin strains faster): at a trial ``x0`` where the
free fit would slow down, the constrained fit is the straight line (``c = 0``), so an S-shaped
curve's early slowing-down is never taken for its threshold.

A hinge fits every curve, also one that bends evenly (a parabola's best hinge sits at its middle
whatever its curvature), so whether a curve HAS a threshold is decided apart, by a
:class:`ThresholdRule` (configuration, the same for a truth and its estimate): the growth rate must
rise by at least ``min_rise`` at the hinge (the paper: strains "increase drastically" past the
threshold) and the change must be significant (``p_value < alpha``). A curve whose rate rises by
8 % over its motion then has no threshold, rather than one at a place that noise decides.

The one definition, for every curve a report or a benchmark reads: :meth:`ThresholdRule.find`
(the rising hinge, judged by the rule) gives a :class:`Finding`: a threshold with its interval, or
none (with why), the hinge's own figures kept beside either answer.

A pure function of arrays, no model: layer 0 of refine, beside :mod:`refine.measures`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from jaxtyping import Float
from scipy import optimize, stats

from refine.exceptions import ObservationError

MIN_SAMPLES = 6
"""Fewest samples a threshold is looked for in: four unknowns (a, b, c, x0) and two left for the noise."""


@dataclass(frozen=True)
class Threshold:
    """Where a curve's growth rate changes.

    Attributes:
        motion: the threshold, in the motion's unit; interval: its ``(low, high)`` interval at ``level``.
        fraction: the threshold as a fraction of the total motion (0 at the first sample, 1 at the
            last); fraction_interval: the interval as fractions.
        std: a standard error of the threshold (the interval's half width over the normal quantile
            of ``level``; motion's unit), for reports that give one number.
        slopes: growth rates ``(before, after)`` (strain per unit motion).
        p_value: of the F test of two segments against one line (small: the rate does change).
        noise: the residuals' standard deviation (strain unit); level: the interval's confidence.
    """

    motion: float
    interval: tuple[float, float]
    fraction: float
    fraction_interval: tuple[float, float]
    std: float
    slopes: tuple[float, float]
    p_value: float
    noise: float
    level: float

    @property
    def rise(self) -> float:
        """How many times faster the curve grows after the threshold than before, ``slopes[1] /
        slopes[0]`` (``inf`` where it was flat or falling before and grows after; ``0`` where it
        grew before and falls or stalls after)."""
        before, after = self.slopes
        if before * after > 0:
            return float(after / before)
        return float("inf") if abs(after) > abs(before) else 0.0

    def to_json(self) -> dict:
        return {"motion": self.motion, "interval": list(self.interval), "fraction": self.fraction,
                "fraction_interval": list(self.fraction_interval), "std": self.std, "slopes": list(self.slopes),
                "rise": self.rise, "p_value": self.p_value, "noise": self.noise, "level": self.level}


@dataclass(frozen=True)
class ThresholdRule:
    """When a curve has a threshold at all (see the module's docstring): its :class:`Threshold`'s
    growth rate rises at least ``min_rise`` times (dimensionless, > 1) and the change is significant
    (F test ``p_value < alpha``). Apply the same rule to a truth and to its estimate."""

    min_rise: float = 1.25
    alpha: float = 0.01

    def __post_init__(self):
        if not self.min_rise > 1:
            raise ObservationError(f"min_rise must exceed 1 (a rate that rises), got {self.min_rise}")
        if not 0 < self.alpha < 1:
            raise ObservationError(f"alpha must be between 0 and 1, got {self.alpha}")

    def holds(self, threshold: Threshold) -> bool:
        """Whether ``threshold`` is one by this rule."""
        return threshold.p_value < self.alpha and threshold.rise >= self.min_rise

    def find(self, motion: Float[np.ndarray, "n"], strain: Float[np.ndarray, "n"], level: float = 0.95) -> Finding:
        """The threshold of the curve ``strain`` (e.g. the maximum strain per frame) against ``motion``
        (any unit, strictly monotone), or none: the rising hinge (:func:`strain_threshold` with
        ``rising=True``, interval at ``level``) judged by this rule.

        Raises:
            ObservationError: as :func:`strain_threshold` (too few samples, shapes, non-finite
                values, a motion that is not strictly monotone).
        """
        hinge = strain_threshold(motion, strain, level=level, rising=True)
        return Finding(hinge, self.holds(hinge), self)

    def to_json(self) -> dict:
        return {"min_rise": self.min_rise, "alpha": self.alpha}


@dataclass(frozen=True)
class Finding:
    """What :meth:`ThresholdRule.find` says of a curve.

    Attributes:
        hinge: the rising hinge (:class:`Threshold`), whether or not it is a threshold.
        found: whether the curve has a threshold by ``rule``; rule: the :class:`ThresholdRule`.
    """

    hinge: Threshold
    found: bool
    rule: ThresholdRule

    @property
    def threshold(self) -> Threshold | None:
        """The threshold (its place and interval), ``None`` where the curve has none."""
        return self.hinge if self.found else None

    @property
    def why_none(self) -> str | None:
        """Why the curve has no threshold (``None`` where it has one)."""
        if self.found:
            return None
        h, r = self.hinge, self.rule
        why = [f"no significant change of the growth rate (F test p = {h.p_value:.2g} >= {r.alpha:g})"] * (
            h.p_value >= r.alpha)
        rises = f"rises only {h.rise:.3g}x" if h.rise > 1 else "does not rise"
        why += [f"the growth rate {rises} at the best hinge ({100 * h.fraction:.0f} % of the motion), "
                f"< {r.min_rise:g}x: no drastic speed-up"] * (h.rise < r.min_rise)
        return "; ".join(why)

    def to_json(self) -> dict:
        """``has_threshold``; where there is one its place ``motion`` (motion's unit) and ``fraction``
        with their 95 % ``interval`` / ``fraction_interval`` and ``std`` (as :meth:`Threshold.to_json`,
        at the top level); where there is none ``why_none``; always the ``hinge`` and the ``rule``."""
        top = {k: v for k, v in self.hinge.to_json().items() if k in ("motion", "interval", "fraction",
                                                                       "fraction_interval", "std", "level")}
        return ({"has_threshold": self.found} | (top if self.found else {"why_none": self.why_none})
                | {"hinge": self.hinge.to_json(), "rule": self.rule.to_json()})


def strain_threshold(motion: Float[np.ndarray, "n"], strain: Float[np.ndarray, "n"], level: float = 0.95,
                     grid: int = 400, rising: bool = False) -> Threshold:
    """The threshold where ``strain`` (e.g. the maximum strain per frame) changes its growth rate
    against ``motion`` (displacement or load per frame, strictly monotone; any unit), with its
    profile-likelihood interval at ``level`` (see the module's docstring). ``grid``: trial
    thresholds before the refinement; ``rising``: only a change to faster growth (see the module).

    Raises:
        ObservationError: fewer than :data:`MIN_SAMPLES` samples, shapes that differ, values
            that are not finite, or a motion that is not strictly monotone.
    """
    x, s = _checked(motion, strain)
    if not 0 < level < 1:
        raise ObservationError(f"level must be between 0 and 1, got {level}")
    flip = x[-1] < x[0]  # a motion that decreases: thresholds are found on its mirror image
    t = -x if flip else x
    n = len(t)
    trials = np.linspace(t[1], t[-2], grid)
    rss = _rss(t, s, trials, rising)
    i = int(np.argmin(rss))
    lo, hi = trials[max(i - 1, 0)], trials[min(i + 1, grid - 1)]
    best = optimize.minimize_scalar(lambda v: _rss(t, s, np.array([v]), rising)[0], bounds=(lo, hi), method="bounded",
                                    options={"xatol": 1e-10 * (t[-1] - t[0])})
    x0, rss_min = (best.x, best.fun) if best.fun <= rss[i] else (trials[i], rss[i])
    dof = n - 4
    s2 = max(rss_min / dof, np.finfo(float).tiny)
    limit = stats.f.ppf(level, 1, dof)
    inside = lambda v: (_rss(t, s, np.array([v]), rising)[0] - rss_min) / s2 - limit  # noqa: E731 - < 0 inside
    out = (rss - rss_min) / s2 > limit
    lo_t = _edge(inside, x0, trials[trials < x0][::-1], out[trials < x0][::-1], t[1])
    hi_t = _edge(inside, x0, trials[trials > x0], out[trials > x0], t[-2])
    coef = _coefficients(t, s, x0)
    line = np.polyfit(t, s, 1)
    if rising and coef[2] < 0:  # no faster growth anywhere: the constrained fit is the line
        coef = np.array([line[1], line[0], 0.0])
    rss_line = float(np.sum((np.polyval(line, t) - s) ** 2))
    F = max(rss_line - rss_min, 0.0) / 2 / s2  # the hinge adds c and x0
    p = float(stats.f.sf(F, 2, dof))
    sign = -1.0 if flip else 1.0
    slopes = (sign * coef[1], sign * (coef[1] + coef[2]))
    at, ends = sign * x0, sorted((sign * lo_t, sign * hi_t))
    span = x[-1] - x[0]
    frac = lambda v: float((v - x[0]) / span)  # noqa: E731
    fr = sorted((frac(ends[0]), frac(ends[1])))
    z = stats.norm.ppf(0.5 + level / 2)
    return Threshold(float(at), (float(ends[0]), float(ends[1])), frac(at), (fr[0], fr[1]),
                     float((ends[1] - ends[0]) / (2 * z)), (float(slopes[0]), float(slopes[1])), p,
                     float(np.sqrt(s2)), level)


def _checked(motion, strain):
    x, s = np.asarray(motion, float), np.asarray(strain, float)
    if x.ndim != 1 or s.shape != x.shape:
        raise ObservationError(f"motion and strain must be 1D of one length, got shapes {x.shape} and {s.shape}")
    if len(x) < MIN_SAMPLES:
        raise ObservationError(f"a threshold needs at least {MIN_SAMPLES} samples of the curve (two segments "
                               f"and the noise), got {len(x)}: record more frames of the motion")
    for name, v in (("motion", x), ("strain", s)):
        bad = np.flatnonzero(~np.isfinite(v))
        if bad.size:
            raise ObservationError(f"{name} is not finite at sample(s) {bad[:5].tolist()}: drop those frames "
                                   "from both arrays first")
    d = np.diff(x)
    if not (np.all(d > 0) or np.all(d < 0)):
        k = int(np.flatnonzero(np.sign(d) != np.sign(x[-1] - x[0]))[0]) if x[-1] != x[0] else 0
        raise ObservationError(f"the motion must be strictly monotone (each frame further than the last); it "
                               f"turns or stalls between samples {k} and {k + 1} ({x[k]:.6g} -> {x[k + 1]:.6g}): "
                               "give one loading branch, sorted")
    return x, s


def _design(t, x0):
    return np.stack([np.ones_like(t), t, np.maximum(t - x0, 0.0)], axis=-1)


def _coefficients(t, s, x0):
    return np.linalg.lstsq(_design(t, x0), s, rcond=None)[0]


def _rss(t, s, trials, rising: bool = False) -> np.ndarray:
    """``RSS(x0)`` of the hinge fit for every trial ``x0`` (least squares on centred, scaled
    columns, batched over the trials); ``rising``: with ``c >= 0`` (the line's RSS where the free
    fit has ``c < 0``)."""
    scale = t[-1] - t[0]
    u = (t - t[0]) / scale
    knots = (np.asarray(trials, float)[:, None] - t[0]) / scale
    A = np.stack(np.broadcast_arrays(np.ones_like(u), u, np.maximum(u - knots, 0.0)), axis=-1)  # (g, n, 3)
    AtA = np.einsum("gni,gnj->gij", A, A) + 1e-14 * np.eye(3)
    Atb = np.einsum("gni,n->gi", A, s)
    c = np.linalg.solve(AtA, Atb[..., None])[..., 0]
    r = np.einsum("gni,gi->gn", A, c) - s
    rss = np.einsum("gn,gn->g", r, r)
    if not rising:
        return rss
    line = np.polyval(np.polyfit(u, s, 1), u) - s
    return np.where(c[:, 2] >= 0, rss, line @ line)


def _edge(inside, x0: float, trials, out, end: float) -> float:
    """Where the profile first crosses the interval's limit going away from ``x0`` through
    ``trials`` (``out``: the trials outside it), bisected between the last trial inside and the
    first outside; ``end`` where it never does."""
    k = np.flatnonzero(out)
    if not k.size:
        return float(end)
    last = x0 if k[0] == 0 else trials[k[0] - 1]
    return float(optimize.brentq(inside, last, trials[k[0]], xtol=1e-12 * max(abs(end), 1.0)))
