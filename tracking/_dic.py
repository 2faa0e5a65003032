"""Subset correlation: inverse-compositional Gauss-Newton (IC-GN) with an affine shape function.

For every point a square reference subset of (2M+1)^2 pixels is matched in the target image
under the first-order warp
    x' = x + u + ux dx + uy dy,   y' = y + v + vx dx + vy dy,   p = (u, ux, uy, v, vx, vy),
minimising the zero-normalised sum of squared differences (ZNSSD, insensitive to offset and
scale of the grey levels). The inverse-compositional update keeps the Hessian of the reference
subset fixed (computed once), and the target is sampled with B-spline interpolation (Pan et
al., Exp. Mech. 2013; the DIC Good Practices Guide, 2018). All points iterate together in arrays.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._interp import SplineImage


@dataclass(frozen=True)
class Subsets:
    """Reference subsets of n points, P pixels each.

    Attributes:
        centres: (n, 2) integer pixel centres (x, y) in the reference image.
        offsets: (P, 2) pixel offsets (dx, dy) of a subset.
        zero_mean: (n, P) reference grey values minus their mean.
        norm: (n,) sqrt of the sum of squares of ``zero_mean``.
        jacobian: (n, P, 6) steepest-descent images dI/dp.
        inverse_hessian: (n, 6, 6).
    """

    centres: np.ndarray
    offsets: np.ndarray
    zero_mean: np.ndarray
    norm: np.ndarray
    jacobian: np.ndarray
    inverse_hessian: np.ndarray

    def take(self, index: np.ndarray) -> "Subsets":
        """The subsets of the points ``index``."""
        return Subsets(self.centres[index], self.offsets, self.zero_mean[index], self.norm[index],
                       self.jacobian[index], self.inverse_hessian[index])


def subset_offsets(radius: int) -> np.ndarray:
    """(P, 2) offsets (dx, dy) of a square subset of side 2 radius + 1."""
    d = np.arange(-radius, radius + 1, dtype=np.float64)
    dy, dx = np.meshgrid(d, d, indexing="ij")
    return np.stack([dx.ravel(), dy.ravel()], axis=1)


def reference_subsets(reference: SplineImage, gradient: tuple[np.ndarray, np.ndarray],
                      centres: np.ndarray, radius: int) -> Subsets:
    """Subsets around integer ``centres`` (n, 2) of the reference, with the spline's exact gradient."""
    centres = np.rint(np.asarray(centres, dtype=np.float64))
    offsets = subset_offsets(radius)
    cols = (centres[:, None, 0] + offsets[None, :, 0]).astype(np.int64)
    rows = (centres[:, None, 1] + offsets[None, :, 1]).astype(np.int64)
    values = reference.image[rows, cols]
    fx, fy = gradient[0][rows, cols], gradient[1][rows, cols]
    dx, dy = offsets[None, :, 0], offsets[None, :, 1]
    jacobian = np.stack([fx, fx * dx, fx * dy, fy, fy * dx, fy * dy], axis=-1)
    zero_mean = values - values.mean(axis=1, keepdims=True)
    norm = np.sqrt(np.sum(zero_mean ** 2, axis=1))
    hessian = np.einsum("npi,npj->nij", jacobian, jacobian)
    with np.errstate(all="ignore"):
        inverse = np.linalg.pinv(hessian)
    return Subsets(centres, offsets, zero_mean, norm, jacobian, inverse)


def warp_matrices(p: np.ndarray) -> np.ndarray:
    """(n, 3, 3) homogeneous affine maps of parameters p (n, 6) = (u, ux, uy, v, vx, vy)."""
    w = np.zeros(p.shape[:1] + (3, 3))
    w[:, 0] = np.stack([1 + p[:, 1], p[:, 2], p[:, 0]], axis=1)
    w[:, 1] = np.stack([p[:, 4], 1 + p[:, 5], p[:, 3]], axis=1)
    w[:, 2, 2] = 1.0
    return w


def warp_parameters(w: np.ndarray) -> np.ndarray:
    """Inverse of :func:`warp_matrices`."""
    return np.stack([w[:, 0, 2], w[:, 0, 0] - 1, w[:, 0, 1],
                     w[:, 1, 2], w[:, 1, 0], w[:, 1, 1] - 1], axis=1)


@dataclass(frozen=True)
class Match:
    """IC-GN result for n points: p (n, 6), zncc (n,), converged (n,) bool, iterations (n,) int."""

    p: np.ndarray
    zncc: np.ndarray
    converged: np.ndarray
    iterations: np.ndarray


def _sample(target: SplineImage, subsets: Subsets, p: np.ndarray, index: np.ndarray):
    dx, dy = subsets.offsets[None, :, 0], subsets.offsets[None, :, 1]
    c = subsets.centres[index]
    x = c[:, :1] + dx + p[:, :1] + p[:, 1:2] * dx + p[:, 2:3] * dy
    y = c[:, 1:] + dy + p[:, 3:4] + p[:, 4:5] * dx + p[:, 5:6] * dy
    inside = target.inside(x, y, margin=1.0).all(axis=1)
    return target.values(x, y), inside


def icgn(target: SplineImage, subsets: Subsets, p0: np.ndarray, max_iterations: int = 30,
         tolerance: float = 1e-3) -> Match:
    """Match every reference subset in ``target`` starting from p0 (n, 6).

    Convergence when the update's displacement at the subset's edge falls under ``tolerance`` px.
    A point whose warped subset leaves the image, or whose update stays large, is not converged.
    """
    n = len(subsets.centres)
    p = np.array(p0, dtype=np.float64).reshape(n, 6)
    radius = float(np.abs(subsets.offsets).max())
    converged = np.zeros(n, bool)
    failed = np.zeros(n, bool)
    iterations = np.zeros(n, np.int64)
    active = np.arange(n)
    for _ in range(max_iterations):
        if active.size == 0:
            break
        g, inside = _sample(target, subsets, p[active], active)
        g_zero = g - g.mean(axis=1, keepdims=True)
        g_norm = np.sqrt(np.sum(g_zero ** 2, axis=1))
        ratio = subsets.norm[active] / np.maximum(g_norm, 1e-12)
        error = subsets.zero_mean[active] - ratio[:, None] * g_zero
        gradient = np.einsum("npi,np->ni", subsets.jacobian[active], error)
        dp = -np.einsum("nij,nj->ni", subsets.inverse_hessian[active], gradient)
        w = warp_matrices(p[active]) @ np.linalg.inv(warp_matrices(dp))
        p[active] = warp_parameters(w)
        iterations[active] += 1
        gradient_step = np.sum(dp[:, [1, 2, 4, 5]] ** 2, axis=1)
        size = np.sqrt(dp[:, 0] ** 2 + dp[:, 3] ** 2 + radius ** 2 * gradient_step)
        done = (size < tolerance) & inside
        converged[active[done]] = True
        # a subset may pass the image border on the way; only the final position must be inside
        failed[active[~np.isfinite(size)]] = True
        active = active[~done & np.isfinite(size)]
    zncc = np.full(n, -1.0)
    ok = ~failed & np.isfinite(p).all(axis=1)
    index = np.nonzero(ok)[0]
    if index.size:
        g, inside = _sample(target, subsets, p[index], index)
        g_zero = g - g.mean(axis=1, keepdims=True)
        denominator = subsets.norm[index] * np.sqrt(np.sum(g_zero ** 2, axis=1))
        zncc[index] = np.sum(subsets.zero_mean[index] * g_zero, axis=1) / np.maximum(denominator, 1e-12)
        converged[index[~inside]] = False
    converged &= ok
    return Match(p, zncc, converged, iterations)
