"""Sub-pixel crossings by fitting the two lines locally to the intensity (the default refiner).

Each line through a crossing is followed along both arms, away from the crossing itself. At
every station, the intensity profile across the line must be mirror symmetric about the line's
centre; the centre line is modelled in the local frame (tau along the line) as a straight line
m(tau) = m0 + m1 tau (optionally a parabola, + m2 tau^2), plus a linear intensity trend b across
it for uneven lighting. The parameters are fitted by Gauss-Newton on the asymmetry residuals
I(centre + u n) - I(centre - u n) - 2 b u, sampled on the quintic B-spline interpolant; this
needs no model of the line's profile (any width, blur or paint). Stations that are far less
symmetric than is typical (an occluding edge, dirt) are then dropped and the fit repeated. The
crossing is where the two fitted lines meet. Quality is the fraction of the profiles' variance
that is symmetric (min over the two lines), set to 0 when fewer than three of the four arms
show a line or when the crossing itself shows no ink (occlusion, dirt).

Straight or curved: with no data at the crossing itself a parabola's offset is an extrapolation
whose noise is larger (0.019 against 0.012 px RMS at noise sigma 2), and on smoothly varying
strain a straight fit's bias stays under 0.005 px at 20 % strain. But where the strain changes
abruptly, at the edge of a stiff inclusion, grid lines bend within a pitch and straight fits
miss the crossings by 0.13 px RMS (rendered sheet with a stiff disc, 15 % pull, pitch 12 px),
parabolas by 0.05 px. The default, ``shape="adaptive"``, fits both per line and keeps the
parabola only where it lowers the asymmetry by more than an information criterion asks for
its extra parameter (0.07 px at those edges, 0.015 px elsewhere).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._crossings import CrossingGuess, GridFrame, Refined, spacing_or
from ._errors import OptionError

SHAPES = ("straight", "curved", "adaptive")
# weight of the parameter count in the information criterion of shape="adaptive" (x log n, n the
# profile samples of the line): at 0.5 nearly every line became a parabola (reference frames as
# noisy as with "curved"), at 3 most lines at a stiff inclusion's edge stayed straight
PENALTY = 2.0
# a crossing whose asymmetry share is this many times the frame's median one is rejected
OUTLIER = 4.0


@dataclass(frozen=True)
class LineFitRefiner:
    """Symmetric-profile line fitting.

    Attributes:
        stations: stations per arm.
        shape: centre line of each grid line through the crossing: "straight", "curved" (a
            parabola) or "adaptive" (per line, the parabola where the data ask for it).
        samples: profile samples on each side of the line.
        iterations: Gauss-Newton iterations per pass (then 2 more after dropping outlier stations).
        passes: fits around successively refined crossings.
        min_quality: below this symmetry score the crossing is not accepted.
        contrast: typical line contrast (grey levels); stations under half of it (occluded, off
            the grid) are ignored. None: the median over all crossings of the frame.
    """

    stations: int = 6
    samples: int = 8
    shape: str = "adaptive"
    iterations: int = 3
    passes: int = 1
    min_quality: float = 0.8
    contrast: float | None = None

    def __post_init__(self):
        if self.shape not in SHAPES:
            raise OptionError(f"unknown centre-line shape {self.shape!r}; use one of {', '.join(SHAPES)}")

    def refine(self, frame: GridFrame, guess: CrossingGuess) -> Refined:
        n = len(guess.xy)
        if n == 0:
            return Refined(np.zeros((0, 2)), np.zeros(0), np.zeros(0, bool))
        pitch, width = frame.pitch, frame.line_width
        row_gap = spacing_or(guess.row_spacing, pitch)
        col_gap = spacing_or(guess.col_spacing, pitch)
        centre = guess.xy.copy()
        tangents = np.stack([guess.row_dir, guess.col_dir], axis=1)          # (N, 2 lines, 2)
        along = np.stack([row_gap, col_gap], axis=1)                          # (N, 2, 2 sides)
        across = np.stack([col_gap.min(axis=1), row_gap.min(axis=1)], axis=1)  # (N, 2)
        shapes = ("straight", "curved") if self.shape == "adaptive" else (self.shape,)
        for _ in range(self.passes):
            normals = np.stack([-tangents[..., 1], tangents[..., 0]], axis=-1)
            sine = np.abs(tangents[:, 0, 0] * tangents[:, 1, 1]
                          - tangents[:, 0, 1] * tangents[:, 1, 0])[:, None]
            clear = (0.5 * width + 1.0) / np.maximum(sine, 0.3)             # crossing's half extent
            tau = self._stations(along, clear)                                # (N, 2, S)
            half = np.minimum(0.5 * width + 2.0, 0.45 * across)               # (N, 2)
            u = half[..., None] * (np.arange(1, self.samples + 1) / self.samples)  # (N, 2, J)
            fits = [self._fit(frame, centre, tangents, normals, tau, u, name == "curved") for name in shapes]
            # per line, the shape with the lowest information criterion (the parabola has one more
            # parameter: it must lower the asymmetry by more than its extra noise is worth)
            count = np.stack([f.count for f in fits])                         # (shapes, N, 2)
            ssr = np.stack([f.ssr for f in fits])
            free = np.arange(len(shapes))[:, None, None]
            criterion = count * np.log(ssr / np.maximum(count, 1.0) + 1e-12) + PENALTY * free * np.log(
                np.maximum(count, 2.0))
            best = np.argmin(criterion, axis=0)[None, ..., None]
            params = np.take_along_axis(np.stack([f.params for f in fits]), best, axis=0)[0]
            score = np.take_along_axis(np.stack([f.score for f in fits]), best[..., 0], axis=0)[0]
            centre, tangents = self._meet(centre, tangents, normals, params)
        fit = fits[0]
        quality = score.min(axis=1)
        # evidence: three of the four arms seen, and ink at the crossing itself (not occluded)
        inked = (frame.spline.values(centre[:, 0], centre[:, 1]) - fit.edge) / fit.depth >= 0.5
        quality = np.where((fit.arms >= 3) & inked, quality, 0.0)
        moved = np.linalg.norm(centre - guess.xy, axis=1)
        inside = frame.spline.inside(centre[:, 0], centre[:, 1], margin=0.5 * frame.pitch)
        ok = np.isfinite(centre).all(axis=1) & (quality >= self._floor(quality)) & inside
        ok &= moved < max(1.5, 0.5 * width)
        return Refined(np.where(ok[:, None], centre, np.nan), quality, ok)

    def _floor(self, quality: np.ndarray) -> float:
        """The quality a crossing must reach: ``min_quality``, and an asymmetry share at most
        :data:`OUTLIER` times the frame's median one (noise lowers every crossing's quality
        alike; one whose arms are cut or caught on something stands out below the others)."""
        seen = quality[quality > 0]
        if seen.size < 8:
            return self.min_quality
        return max(self.min_quality, 1.0 - OUTLIER * (1.0 - float(np.median(seen))))

    def _stations(self, along, clear):
        fractions = (np.arange(self.stations) + 0.5) / self.stations
        start = clear[..., None]                                              # (N, 2, 1)
        stop = np.maximum(along - clear[..., None], start + 1.0)              # (N, 2, 2)
        before = -(start + fractions * (stop[..., :1] - start))
        after = start + fractions * (stop[..., 1:] - start)
        return np.concatenate([before[..., ::-1], after], axis=-1)            # (N, 2, 2K)

    def _fit(self, frame, centre, tangents, normals, tau, u, curved: bool) -> "_LineFit":
        """Fit both lines of every crossing: straight centre lines, or parabolas if ``curved``."""
        spline = frame.spline
        basis = np.stack([np.ones_like(tau), tau, tau ** 2], axis=-1)         # (N, L, S, 3)
        k = basis.shape[-1]
        base = centre[:, None, None, :] + tau[..., None] * tangents[:, :, None, :]   # (N, L, S, 2)
        nn = normals[:, :, None, None, :]                                     # (N, L, 1, 1, 2)

        def sample(offset):                                                   # offset (N, L, S, J)
            xy = base[:, :, :, None, :] + offset[..., None] * nn
            return spline.values(xy[..., 0], xy[..., 1])

        params = np.zeros(centre.shape[:1] + (2, k + 1))                      # basis, then trend b
        uu = u[:, :, None, :]                                                 # (N, L, 1, J)
        ridge = np.diag([1e-6, 1e-6, 1e-6 if curved else 1e6, 1e-6])
        for iteration in range(self.iterations + 2):
            m = np.einsum("nlsk,nlk->nls", basis, params[..., :k])[..., None]  # (N, L, S, 1)
            plus, minus = sample(m + uu), sample(m - uu)
            residual = plus - minus - 2.0 * params[..., k][..., None, None] * uu
            if iteration == 0:
                eps = 0.5
                slope = (sample(m + uu + eps) - sample(m + uu - eps)
                         - sample(m - uu + eps) + sample(m - uu - eps)) / (2 * eps)
                jac = np.concatenate([slope[..., None] * basis[:, :, :, None, :],
                                      np.broadcast_to(-2.0 * uu[..., None], slope.shape + (1,))], axis=-1)
                profile = np.concatenate([plus, minus], axis=-1)
                contrast = profile.max(axis=-1) - profile.min(axis=-1)       # (N, L, S)
                # stations off the line (grid edge) or reaching the image border carry no weight
                typical = np.median(contrast) if self.contrast is None else self.contrast
                weight = (contrast >= 0.5 * typical).astype(float)
                ends = [base[:, :, :, None, :] + (m + sign * uu[..., -1:])[..., None] * nn
                        for sign in (1, -1)]
                weight *= np.all([spline.inside(e[..., 0], e[..., 1], margin=2.0)[..., 0]
                                  for e in ends], axis=0)
            if iteration in (0, self.iterations):
                if iteration == self.iterations:
                    # robust stage: drop stations far less symmetric than is typical (an occluding
                    # edge, dirt, a neighbouring line's end) and fit again
                    rms = np.sqrt(np.mean(residual ** 2, axis=-1))
                    typical_rms = np.median(rms[weight > 0]) if np.any(weight > 0) else 0.0
                    weight = weight * (rms <= 4.0 * typical_rms + 1e-9)
                normal = np.einsum("nlsjp,nlsjq,nls->nlpq", jac, jac, weight)
                scale = np.einsum("nlpp->nlp", normal).max(axis=-1)[..., None, None] + 1e-9
                normal = normal + scale * ridge
            rhs = np.einsum("nlsjp,nlsj,nls->nlp", jac, residual, weight)
            step = np.linalg.solve(normal, -rhs[..., None])[..., 0]
            step[..., 0] = np.clip(step[..., 0], -1.0, 1.0)
            params = params + step
        m = np.einsum("nlsk,nlk->nls", basis, params[..., :k])[..., None]
        plus, minus = sample(m + uu), sample(m - uu)
        residual = (plus - minus - 2.0 * params[..., k][..., None, None] * uu) * weight[..., None]
        mean = 0.5 * (plus + minus).mean(axis=-1, keepdims=True)
        spread = ((plus - mean) ** 2 + (minus - mean) ** 2) * weight[..., None]
        ssr = 0.5 * np.sum(residual ** 2, axis=(2, 3))
        sst = np.sum(spread, axis=(2, 3)) + 1e-12
        score = np.where(weight.sum(axis=-1) >= 3, 1.0 - ssr / sst, 0.0)     # 3 stations at least
        half = weight.shape[-1] // 2
        arms = ((weight[..., :half].sum(axis=-1) >= 2).sum(axis=1)
                + (weight[..., half:].sum(axis=-1) >= 2).sum(axis=1))
        total = np.maximum(weight.sum(axis=(1, 2)), 1.0)
        outer = 0.25 * (plus[..., -2:].sum(-1) + minus[..., -2:].sum(-1))
        edge = np.sum(outer * weight, axis=(1, 2)) / total
        middle = np.sum(0.5 * (plus[..., 0] + minus[..., 0]) * weight, axis=(1, 2)) / total
        depth = middle - edge
        depth = np.where(np.abs(depth) > 1e-9, depth, np.nan)
        count = weight.sum(axis=-1) * uu.shape[-1]
        return _LineFit(params[..., :k], ssr, count, np.clip(score, 0.0, 1.0), arms, edge, depth)

    @staticmethod
    def _meet(centre, tangents, normals, params):
        """Crossing of the two fitted centre lines (parabolas) and the line directions there."""
        a = np.zeros(len(centre))                                             # position on row line
        b = np.zeros(len(centre))                                             # position on column line
        t0, t1 = tangents[:, 0], tangents[:, 1]
        n0, n1 = normals[:, 0], normals[:, 1]
        p0, p1 = params[:, 0], params[:, 1]

        def curve(s, t, nrm, p):
            m = p[:, 0] + p[:, 1] * s + p[:, 2] * s ** 2
            dm = p[:, 1] + 2 * p[:, 2] * s
            return s[:, None] * t + m[:, None] * nrm, t + dm[:, None] * nrm

        for _ in range(6):
            pa, da = curve(a, t0, n0, p0)
            pb, db = curve(b, t1, n1, p1)
            jac = np.stack([da, -db], axis=-1)                                # (N, 2, 2)
            det = jac[:, 0, 0] * jac[:, 1, 1] - jac[:, 0, 1] * jac[:, 1, 0]
            det = np.where(np.abs(det) < 1e-9, np.nan, det)
            f = pa - pb
            a = a - (jac[:, 1, 1] * f[:, 0] - jac[:, 0, 1] * f[:, 1]) / det
            b = b - (-jac[:, 1, 0] * f[:, 0] + jac[:, 0, 0] * f[:, 1]) / det
        pa, da = curve(a, t0, n0, p0)
        _, db = curve(b, t1, n1, p1)
        new_t = np.stack([da / np.linalg.norm(da, axis=1, keepdims=True),
                          db / np.linalg.norm(db, axis=1, keepdims=True)], axis=1)
        return centre + pa, new_t


@dataclass(frozen=True)
class _LineFit:
    """Both lines of N crossings: params (N, 2, 3) of m(tau) = m0 + m1 tau + m2 tau^2; ssr, count
    and score (N, 2): asymmetry left, samples used, symmetric share of the variance; arms (N,)
    seen; edge and depth (N,): grey level of the sheet next to the lines, ink depth at their centre."""

    params: np.ndarray
    ssr: np.ndarray
    count: np.ndarray
    score: np.ndarray
    arms: np.ndarray
    edge: np.ndarray
    depth: np.ndarray
