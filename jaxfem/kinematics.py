"""Kinematic assumptions: how an in-plane (2x2) or full (3x3) deformation gradient becomes the 3x3
F that a material's energy takes.

- ``solid``: F is already 3x3.
- ``plane-strain``: F33 = 1.
- ``plane-stress``: F33 = lambda3 is the stretch that makes the out-of-plane stress vanish at each
  quadrature point, d psi / d F33 = 0, solved by Newton's method. Its derivatives come from the
  implicit function theorem (a ``custom_jvp``), so residuals, tangents and every higher derivative
  of the reduced energy are exact. This is what a thin sheet needs; it is not the plane-strain law.
"""

from __future__ import annotations

from typing import Callable

import jax
import jax.numpy as jnp

from . import _config  # noqa: F401

KINDS = ("plane-stress", "plane-strain", "solid")
_NEWTON_ITERS = 12


def embed(F2, f33):
    """3x3 deformation gradient from an in-plane 2x2 block and an out-of-plane stretch."""
    F = jnp.zeros((3, 3), F2.dtype).at[:2, :2].set(F2)
    return F.at[2, 2].set(f33)


def _plane_stress_stretch(energy: Callable) -> Callable:
    """Build ``lambda3(F2, p)`` for one energy: the root of d psi(embed(F2, l)) / dl = 0."""

    def h(l, F2, p):
        return jax.grad(lambda s: energy(embed(F2, s), p))(l)

    def newton(F2, p):
        nu = p["nu"]
        # Start from the small-strain plane-stress estimate eps33 = -nu/(1-nu) (eps11 + eps22).
        l0 = 1.0 - nu / (1.0 - nu) * (F2[0, 0] + F2[1, 1] - 2.0)
        l0 = jnp.clip(l0, 0.2, 5.0)

        def body(_, l):
            hl = jax.grad(h)(l, F2, p)
            step = h(l, F2, p) / hl
            # keep the stretch positive: never move more than halfway to zero
            return jnp.maximum(l - step, 0.5 * l)

        return jax.lax.fori_loop(0, _NEWTON_ITERS, body, l0)

    @jax.custom_jvp
    def stretch(F2, p):
        return newton(jax.lax.stop_gradient(F2), jax.lax.stop_gradient(p))

    @stretch.defjvp
    def _stretch_jvp(primals, tangents):
        F2, p = primals
        l = stretch(F2, p)
        hl = jax.grad(h)(l, F2, p)
        _, hdot = jax.jvp(lambda a, b: h(l, a, b), (F2, p), tangents)
        return l, -hdot / hl

    return stretch


def reduced_energy(energy: Callable, kind: str) -> tuple[Callable, Callable]:
    """For a 3D energy psi(F3, p), the energy of the kinematic kind as a function of the element's
    own F (2x2 in plane, 3x3 solid), and the map to the full 3x3 F (for post-processing).

    Returns:
        ``(W(F, p) -> scalar, full_F(F, p) -> (3, 3))``.
    """
    if kind == "solid":
        return energy, lambda F, p: F
    if kind == "plane-strain":
        full = lambda F, p: embed(F, 1.0)  # noqa: E731
    elif kind == "plane-stress":
        stretch = _plane_stress_stretch(energy)
        full = lambda F, p: embed(F, stretch(F, p))  # noqa: E731
    else:
        raise ValueError(f"unknown kinematics {kind!r}; known: {', '.join(KINDS)}")
    return (lambda F, p: energy(full(F, p), p)), full
