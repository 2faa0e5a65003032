"""Checks of derivatives: the Taylor test in the style of dolfin-adjoint.

For a smooth f, |f(theta + h d) - f(theta)| shrinks like h and the first-order remainder
|f(theta + h d) - f(theta) - h df(theta).d| like h^2. Halving h should therefore show rates near
1 and 2; a wrong derivative leaves the second remainder at rate 1.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from . import _config  # noqa: F401
from .exceptions import OptionError


@dataclass(frozen=True)
class TaylorResult:
    """Step sizes, the zeroth- and first-order remainders and their observed convergence rates."""

    h: np.ndarray
    remainder0: np.ndarray
    remainder1: np.ndarray
    rates0: np.ndarray
    rates1: np.ndarray

    @property
    def min_rate(self) -> float:
        """Smallest observed first-order-remainder rate (should be close to 2)."""
        return float(np.min(self.rates1))

    def __str__(self) -> str:
        rows = [f"{'h':>10} {'|f1-f0|':>12} {'|f1-f0-h df.d|':>15} {'rate0':>6} {'rate1':>6}"]
        for i, h in enumerate(self.h):
            r0 = f"{self.rates0[i - 1]:6.2f}" if i else " " * 6
            r1 = f"{self.rates1[i - 1]:6.2f}" if i else " " * 6
            rows.append(f"{h:10.3e} {self.remainder0[i]:12.4e} {self.remainder1[i]:15.4e} {r0} {r1}")
        return "\n".join(rows)


def _axpy(h, d, x):
    return jax.tree.map(lambda a, b: a + h * b, x, d)


def taylor_test(f, theta, direction, h0: float = 1e-2, steps: int = 5, mode: str = "reverse") -> TaylorResult:
    """Taylor test of a scalar function ``f`` of a pytree ``theta`` along ``direction``.

    Args:
        f: ``theta -> scalar``, differentiable by JAX.
        theta: the point (any pytree of float arrays).
        direction: a pytree like ``theta`` (pick it at random, not along the gradient).
        h0: the first step; each next step is half the previous one.
        steps: number of step sizes.
        mode: ``"reverse"`` (df.d from ``jax.grad``) or ``"forward"`` (from ``jax.jvp``).
    Returns:
        :class:`TaylorResult`; ``result.rates1`` should be close to 2.
    """
    f0 = float(f(theta))
    if mode == "reverse":
        g = jax.grad(f)(theta)
        dfd = float(sum(jnp.vdot(a, b) for a, b in zip(jax.tree.leaves(g), jax.tree.leaves(direction))))
    elif mode == "forward":
        dfd = float(jax.jvp(f, (theta,), (direction,))[1])
    else:
        raise OptionError(f"mode must be 'reverse' or 'forward', not {mode!r}")
    h = h0 * 0.5 ** np.arange(steps)
    fh = np.array([float(f(_axpy(hi, direction, theta))) for hi in h])
    r0 = np.abs(fh - f0)
    r1 = np.abs(fh - f0 - h * dfd)
    with np.errstate(divide="ignore", invalid="ignore"):
        return TaylorResult(h, r0, r1, np.log2(r0[:-1] / r0[1:]), np.log2(r1[:-1] / r1[1:]))
