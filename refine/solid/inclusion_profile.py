"""The profile of a fitted inclusion's misfit over its modulus ratio: what surface data say about
an inclusion's volume and ratio, which they trade against each other.

Seen from the surface of a block, an inclusion acts to first order through one number, its
strength ``S = V (r - 1) / (1 + beta (r - 1))`` (mm^3; :func:`strength`: the dilute sphere's
shear polarisability, ``beta = 2 (4 - 5 nu) / (15 (1 - nu))`` Eshelby's factor), which stays
finite as ``r`` grows: a smaller, stiffer inclusion acts alike, so fits can come out small in
volume and extreme in ratio with ``S`` close to the truth's, and linearised standard errors do
not cover the curved volume-ratio valley. So the ratio
and volume are reported as profile-likelihood intervals (:func:`profile_ratio`): the log ratio is
held at values stepped out from the fit on either side, the nine shape unknowns refitted at each
(warm started from the step before), and the interval is where chi^2 rises by at most
``threshold`` (4: two standard errors for one unknown) times the reduced chi^2 of the fit (at
least 1, as :func:`refine.diagnosis.fitted.covariance` scales); the volume's interval is the
range of the refitted volumes over the ratio's interval (the valley is one-dimensional), and the
strength's likewise. An end not reached before :data:`~refine.solid.inclusion.MAX_LOG_RATIO` (or
before ``max_steps``) is open: the data fix only a bound there.

A profile's point is a refit, so it can land lower than the fit it was stepped from where that fit
stopped short along the flat valley: :func:`profiled_fit` then refits from that point and
profiles again about the new minimum, so that the fit reported is the lowest point found and the
intervals are about it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import jax.numpy as jnp
import numpy as np

from refine.diagnosis.fitted import Fitted
from refine.measures import Residuals
from refine.model.objective import Compiled
from refine.optimize.levenberg_marquardt import levenberg_marquardt
from refine.solid.inclusion import MAX_LOG_RATIO, EllipsoidModulus


def strength(volume, ratio, nu: float):
    """An inclusion's strength as surface data see it (mm^3 for ``volume`` in mm^3): ``V (r - 1) /
    (1 + beta (r - 1))``, ``beta = 2 (4 - 5 nu) / (15 (1 - nu))``; positive for a stiffer
    inclusion, negative for a softer one, bounded by ``V / beta`` as ``r`` grows."""
    beta = 2.0 * (4.0 - 5.0 * nu) / (15.0 * (1.0 - nu))
    r = np.asarray(ratio, float)
    return np.asarray(volume, float) * (r - 1.0) / (1.0 + beta * (r - 1.0))


@dataclass(frozen=True, eq=False)
class RatioHeld:
    """``base`` (an :class:`~refine.solid.inclusion.EllipsoidModulus`, or any region's
    parametrisation whose first unknown is the log ratio) with its log ratio held at
    ``log_ratio``: the unknowns ``z`` are the base's others (the centre and shape), started at
    ``start``."""

    base: EllipsoidModulus
    log_ratio: float
    start: np.ndarray

    @property
    def size(self) -> int:
        return self.base.size - 1

    def full(self, z, xp=jnp):
        """The base's unknowns ``(10,)`` at ``z (9,)``."""
        return xp.concatenate([xp.full(1, self.log_ratio), xp.asarray(z, float)])

    @property
    def z0(self):
        return jnp.asarray(self.start, float)

    def apply(self, theta, z):
        return self.base.apply(theta, self.full(z))

    def regularization(self, z):
        return 0.0

    def shape(self, z):
        return self.base.shape(self.full(z, np))

    def infeasibility(self, z) -> str | None:
        return self.base.infeasibility(self.full(z, np))

    def values(self, z) -> dict:
        return self.base.values(self.full(z, np))


@dataclass(frozen=True)
class ProfilePoint:
    """One held log ratio and its refit: ``chi2``, the refitted ``volume`` (mm^3) and ``z (10,)``."""

    log_ratio: float
    chi2: float
    volume: float
    z: tuple


@dataclass
class Profile:
    """A ratio profile (see the module): its ``points`` (sorted by log ratio, the fit among them),
    the ``threshold`` on chi^2 - chi^2_min, the intervals (``ratio``, ``volume``, ``strength``:
    ``(low, high)``) and whether each end of the ratio's is open (``open``: ``(low, high)``)."""

    points: list
    chi2_min: float
    threshold: float
    ratio: tuple
    volume: tuple
    strength: tuple
    open: tuple
    seconds: float = 0.0
    nu: float = 0.3
    evaluations: int = 0
    extra: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        """report.json's content."""
        return {"ratio": list(self.ratio), "volume": list(self.volume), "strength": list(self.strength),
                "open": list(self.open), "threshold": self.threshold, "chi2_min": self.chi2_min,
                "points": [{"ratio": float(np.exp(p.log_ratio)), "chi2": p.chi2, "volume": p.volume,
                            "strength": float(strength(p.volume, np.exp(p.log_ratio), self.nu))} for p in self.points],
                "evaluations": self.evaluations, "seconds": self.seconds}


def interval(points: list, threshold: float, nu: float = 0.3) -> Profile:
    """The intervals of a profile's ``points`` (:class:`ProfilePoint`, any order): where chi^2 -
    min chi^2 <= ``threshold``, its crossings interpolated between the last point inside and the
    first outside, linearly in the log ratio against the square root of the rise (exact for a
    parabola; the volume linearly alike); an end with no point outside is open (at the outermost
    point held)."""
    pts = sorted(points, key=lambda p: p.log_ratio)
    lr = np.array([p.log_ratio for p in pts])
    chi2 = np.array([p.chi2 for p in pts])
    dc, vol = chi2 - chi2.min(), np.array([p.volume for p in pts])
    i0 = int(np.argmin(dc))
    # the rise as the lower envelope outward from the least value: a refit's chi^2 bounds the profile
    # from above, and a valley's profile rises outward, so a point above one farther out is a refit
    # that stopped short (e.g. a fit held back at the ratio's bound) and does not end the interval
    rise = dc.copy()
    rise[:i0] = np.minimum.accumulate(dc[:i0])
    rise[i0 + 1:] = np.minimum.accumulate(dc[i0 + 1:][::-1])[::-1]
    ends, opened = [], []
    for step in (-1, 1):
        i = i0
        while 0 <= i + step < len(pts) and rise[i + step] <= threshold:
            i += step
        j = i + step
        if 0 <= j < len(pts):  # the crossing between i (inside) and j (outside), sqrt(chi2 rise)
            # linear (exact where the profile is a parabola about its least value)
            t = (np.sqrt(threshold) - np.sqrt(rise[i])) / (np.sqrt(rise[j]) - np.sqrt(rise[i]))
            ends.append((lr[i] + t * (lr[j] - lr[i]), vol[i] + t * (vol[j] - vol[i]), i))
            opened.append(False)
        else:
            ends.append((lr[i], vol[i], i))
            opened.append(True)
    (lo, v_lo, i_lo), (hi, v_hi, i_hi) = ends
    inside = np.arange(i_lo, i_hi + 1)
    inside = inside[dc[inside] <= threshold]  # refits that reached the valley
    vols, ratios = np.r_[vol[inside], v_lo, v_hi], np.exp(np.r_[lr[inside], lo, hi])
    s = strength(vols, ratios, nu)
    return Profile(pts, float(chi2.min()), threshold,
                   (float(np.exp(lo)), float(np.exp(hi))), (float(vols.min()), float(vols.max())),
                   (float(s.min()), float(s.max())), tuple(opened), nu=nu)


def held_point(f: Fitted, points, sigma: float, log_ratio: float, start, max_steps: int = 8
               ) -> tuple[ProfilePoint, int]:
    """The profile's point of ``f`` at ``log_ratio``: the nine shape unknowns refitted (LM, at most
    ``max_steps`` evaluations) from ``start (9,)`` with the log ratio held; and the evaluations."""
    held = RatioHeld(f.compiled.param, float(log_ratio), np.asarray(start, float))
    compiled = Compiled(f.model, held, f.compiled.theta)
    res = levenberg_marquardt(compiled, points, sigma, z0=held.start, max_steps=max_steps, chi2_tol=0.2)
    zs = np.asarray(res.values["z"], float)
    c2 = Residuals.at(f.model.obs.displacements, points, sigma).chi2(compiled.predict(zs))
    return ProfilePoint(float(log_ratio), float(c2), held.shape(zs).volume, tuple(held.full(zs, np))), int(res.n_forward)


def profile_ratio(f: Fitted, points, sigma: float, threshold: float = 4.0, max_steps: int = 4,
                  first_step: float | None = None, log=print) -> Profile:
    """The profile of ``f`` (a fitted :class:`~refine.solid.inclusion.Inclusion`) over its log
    ratio on the ``points`` mask with noise ``sigma`` (see the module). Steps start at the log
    ratio's standard error (``f.z_std[0]``, clipped to 0.1-0.5: a larger step can send the refit
    far along the valley) or ``first_step``, grow by half each
    step, stop where chi^2 has risen past the threshold, at the ratio's bound or after
    ``max_steps`` per side; each refit is a Levenberg-Marquardt fit of the nine shape unknowns (the
    fit's own ratio refitted too where the fit ran to the ratio's bound), warm started from the one
    before."""
    import time

    t0 = time.perf_counter()
    base, z = f.compiled.param, np.asarray(f.z, float)
    at = Residuals.at(f.model.obs.displacements, points, sigma)
    scale = max(f.chi2_fit / max(int(at.n) - z.size, 1), 1.0)
    limit = threshold * scale
    chi2_fit = at.chi2(f.compiled.predict(z))

    def refit(lr, zs):
        point, n = held_point(f, points, sigma, lr, zs)
        log(f"    profile: ratio {np.exp(lr):.3g} chi2 {point.chi2 - chi2_fit:+.1f} volume {point.volume:.0f}")
        return point, np.asarray(point.z[1:], float), n

    # the fit's own ratio refitted (from the fit: its chi^2 no higher) where the fit ran to the
    # ratio's bound: held back there it stops short in its shape; elsewhere the fit is its own
    # point (a refit would cost as much as a profile step)
    if abs(float(z[0])) > 0.95 * MAX_LOG_RATIO:
        first, z1, evaluations = refit(float(z[0]), z[1:])
    else:
        first, z1, evaluations = ProfilePoint(float(z[0]), float(chi2_fit), base.shape(z).volume, tuple(z)), z[1:], 0
    found = [first]
    std = float(f.z_std[0]) if f.z_std is not None and np.isfinite(f.z_std[0]) else 0.3
    step0 = first_step if first_step is not None else float(np.clip(std, 0.1, 0.5))
    for sign in (-1.0, 1.0):
        lr, zs, step = float(z[0]), z1, step0
        for _ in range(max_steps):
            if sign * lr >= MAX_LOG_RATIO:  # at the bound already (a fit that ran there): open
                break
            lr = float(np.clip(lr + sign * step, -MAX_LOG_RATIO, MAX_LOG_RATIO))
            point, zs, used = refit(lr, zs)
            found.append(point)
            evaluations += used
            if point.chi2 - min(p.chi2 for p in found) > limit:
                break
            step *= 1.5
    prof = interval(found, limit, nu=float(base.nu))
    prof.seconds, prof.evaluations = time.perf_counter() - t0, evaluations
    return prof


def merged(new: Profile, old: Profile) -> Profile:
    """One profile of both's points (each a refit with the ratio held: an upper bound of the
    profile at its ratio, whichever fit it was stepped from), on ``new``'s threshold; seconds and
    evaluations added."""
    return _joined(list(new.points) + list(old.points), new, new.seconds + old.seconds,
                   new.evaluations + old.evaluations)


def _joined(points, like: Profile, seconds: float, evaluations: int) -> Profile:
    """The profile of ``points`` on ``like``'s threshold and Poisson ratio, with its cost."""
    prof = interval(points, like.threshold, nu=like.nu)
    prof.seconds, prof.evaluations = seconds, evaluations
    return prof


def lowest_point(prof: Profile, chi2_fit: float, tol: float) -> ProfilePoint | None:
    """The profile's lowest point where it lies more than ``tol`` below ``chi2_fit`` (the fit it was
    stepped from stopped short of its minimum: a capped refit along a flat valley); else None."""
    p = min(prof.points, key=lambda q: q.chi2)
    return p if p.chi2 < chi2_fit - tol and len(p.z) else None


def profiled_fit(f, profile, refit, tol: float = 0.5, max_restarts: int = 1, log=print):
    """The fit ``f`` profiled (``profile(f) -> Profile``), and, where the profile finds a point
    lower in chi^2 than ``f`` by more than ``tol`` (:func:`lowest_point`), refitted from that
    point's unknowns (``refit(f, z (10,)) -> fit``, capped by the caller) and profiled again about
    the new minimum, its points joined with the earlier profile's (:func:`merged`), at most
    ``max_restarts`` times; a lower point found after the last is refitted without a new profile,
    the refit joining the profile as its point. So the fit returned is the lowest point found (to
    ``tol``) and the intervals are about it. Returns the fit, its profile and the starts (one dict
    per fit, the first ``f``'s: ``start``, ``ratio``, ``chi2``; a restart's also the point's
    ``point_chi2``)."""
    prof = profile(f)
    starts = [{"start": "fit", "ratio": float(np.exp(np.asarray(f.z)[0])), "chi2": float(f.chi2_fit)}]
    for k in range(max_restarts + 1):
        p = lowest_point(prof, f.chi2_fit, tol)
        if p is None:
            break
        g = refit(f, np.asarray(p.z, float))
        if not g.chi2_fit < f.chi2_fit:  # a refit started lower cannot end higher; never adopt one that did
            log(f"  restart from the profile's point at ratio {np.exp(p.log_ratio):.3g} ended at chi2 "
                f"{g.chi2_fit:.1f}, not below the fit's {f.chi2_fit:.1f}: kept the fit")
            break
        log(f"  the profile's point at ratio {np.exp(p.log_ratio):.3g} lay {f.chi2_fit - p.chi2:.1f} below the fit: "
            f"refitted from it, ratio {np.exp(np.asarray(g.z)[0]):.3g}, chi2 {g.chi2_fit - f.chi2_fit:+.1f}")
        starts.append({"start": "profile point", "ratio": float(np.exp(np.asarray(g.z)[0])), "chi2": float(g.chi2_fit),
                       "point_ratio": float(np.exp(p.log_ratio)), "point_chi2": float(p.chi2),
                       "evaluations": int(getattr(getattr(g, "result", None), "n_forward", 0) or 0)})
        f = g
        if k < max_restarts:
            prof = merged(profile(f), prof)
        else:  # no new profile: the refit is one more point of it
            z = np.asarray(f.z, float)
            point = ProfilePoint(float(z[0]), float(f.chi2_fit), float(f.shapes[0].volume) if f.shapes else np.nan,
                                 tuple(z))
            prof = _joined(list(prof.points) + [point], prof, prof.seconds, prof.evaluations)
    return f, prof, starts
