"""Kinematic assumptions: how an in-plane (2x2) or full (3x3) deformation gradient becomes the 3x3
F that a material's energy takes.

- ``solid``: F is already 3x3.
- ``plane-strain``: F33 = 1.
- ``plane-stress``: F33 = lambda3 is the stretch that makes the out-of-plane stress vanish at each
  quadrature point, d psi / d F33 = 0, solved by Newton's method. Its derivatives come from the
  implicit function theorem (a ``custom_jvp``), so residuals, tangents and every higher derivative
  of the reduced energy are exact. This is what a thin sheet needs; it is not the plane-strain law.

The out-of-plane stretch is also a state the caller may keep: the ``*_state`` functions of
:class:`Reduced` take a start ``l0`` for the stretch's Newton iteration (NaN: none, start from the
small-strain estimate) and return the converged stretch, so that a Newton solve over the whole body
restarts each quadrature point's stretch from the last iterate (one or two iterations instead of
three or four) and a tangent at a state whose stretch is known costs a single check iteration.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Callable

import jax
import jax.numpy as jnp

from . import _config  # noqa: F401
from .exceptions import ProblemError

#: the kinematic assumptions a model may take (the registry of model kinds: the bundle reads it)
KINDS = ("plane-stress", "plane-strain", "solid")
_NEWTON_ITERS = 30
_UNROLLED = 1  # the rest in a loop that stops where every point has converged


def embed(F2, f33):
    """3x3 deformation gradient from an in-plane 2x2 block and an out-of-plane stretch.

    By concatenation, not a scatter: Taylor mode (``jax.experimental.jet``, used by
    :mod:`jaxfem.series`) has no rule for a scatter (and the pass takes the same time either way)."""
    corner = jnp.concatenate([jnp.zeros((1, 2), F2.dtype), jnp.reshape(jnp.asarray(f33, F2.dtype), (1, 1))], axis=1)
    return jnp.concatenate([jnp.concatenate([F2, jnp.zeros((2, 1), F2.dtype)], axis=1), corner], axis=0)


def _plane_stress_stretch(energy: Callable) -> Callable:
    """Build ``lambda3(F2, p)`` for one energy: the root of d psi(embed(F2, l)) / dl = 0."""

    def h(l, F2, p):
        return jax.grad(lambda s: energy(embed(F2, s), p))(l)

    def newton(F2, p, l0):
        nu = p["nu"]
        # Without a start (NaN), the small-strain plane-stress estimate eps33 = -nu/(1-nu) (eps11 +
        # eps22); Newton then converges quadratically (3-4 iterations at 20 % strain; 1-2 from the
        # stretch of a nearby state, 1 from the converged stretch of the same state).
        est = jnp.clip(1.0 - nu / (1.0 - nu) * (F2[0, 0] + F2[1, 1] - 2.0), 0.2, 5.0)
        l0 = jnp.where(jnp.isfinite(l0) & (l0 > 0), l0, est)

        def body(c):
            l, _, k = c
            hv, hl = jax.jvp(lambda s: h(s, F2, p), (l,), (jnp.ones_like(l),))
            # keep the stretch positive: never move more than halfway to zero
            new = jnp.maximum(l - hv / hl, 0.5 * l)
            return new, jnp.abs(new - l), k + 1

        def cond(c):
            # Newton converges quadratically here: after a step below 1e-8 of the stretch the
            # error left is ~1e-16, so that step is the last one needed.
            l, step, k = c
            return (step > 1e-8 * l) & (k < _NEWTON_ITERS)

        # The first iteration unrolled (XLA fuses it into the pass over the quadrature points;
        # a loop iteration is a pass of its own), the rest only while a point still needs them.
        c = (l0, jnp.ones_like(l0), 0)
        for _ in range(_UNROLLED):
            c = body(c)
        return jax.lax.while_loop(cond, body, c)[0]

    @jax.custom_jvp
    def stretch(F2, p, l0):
        return newton(jax.lax.stop_gradient(F2), jax.lax.stop_gradient(p), jax.lax.stop_gradient(l0))

    @stretch.defjvp
    def _stretch_jvp(primals, tangents):
        F2, p, l0 = primals  # the start does not change the root: its tangent is ignored
        l = stretch(F2, p, l0)
        hl = jax.grad(h)(l, F2, p)
        _, hdot = jax.jvp(lambda a, b: h(l, a, b), (F2, p), tangents[:2])
        return l, -hdot / hl

    return stretch


@dataclass(frozen=True)
class Reduced:
    """A material law under one kinematic assumption, as functions of the element's own F
    (2x2 in plane, 3x3 solid) and the per-cell parameter dict ``p``.

    Attributes:
        energy: ``W(F, p)``, energy per reference volume.
        stress: ``P(F, p) = dW/dF`` (first Piola-Kirchhoff, in-plane block in 2D).
        stress_and_tangent: ``(P, A)`` with ``A[m] = dP/dF_m`` for each flattened component m.
        full_F: the 3x3 deformation gradient (with the out-of-plane stretch in 2D).
        stress_state, stress_and_tangent_state: the same with a start ``l0`` for the out-of-plane
            stretch (NaN: none), returning ``(P, l)`` and ``(P, A, l)`` with ``l`` the converged
            stretch, the start for a nearby state (F33 under the other kinematics, unused there).
    """

    energy: Callable
    stress: Callable
    stress_and_tangent: Callable
    full_F: Callable
    stress_state: Callable
    stress_and_tangent_state: Callable


def dimension(kind: str) -> int:
    """The mesh dimension a kinematic ``kind`` takes: 3 for ``solid``, 2 for the plane kinds."""
    if kind not in KINDS:
        raise ProblemError(f"unknown kinematics {kind!r}; use one of {', '.join(KINDS)}")
    return 3 if kind == "solid" else 2


@functools.lru_cache(maxsize=None)
def reduce(energy: Callable, kind: str) -> Reduced:
    """Specialise a 3D energy psi(F3, p) to the kinematic ``kind``.

    For plane stress the in-plane tangent is the derivative of the in-plane stress with the
    out-of-plane stretch following F (the Hessian of psi condensed on the stretch, exact because
    d psi/d F33 = 0 there); every derivative comes from JAX, and derivatives through the stretch
    use its implicit ``custom_jvp``.
    """
    d = dimension(kind)
    if kind == "plane-stress":
        stretch = _plane_stress_stretch(energy)
        full3 = lambda F, p, l0: embed(F, stretch(F, p, l0))  # noqa: E731
    elif kind == "plane-strain":
        full3 = lambda F, p, l0: embed(F, 1.0)  # noqa: E731
    else:
        full3 = lambda F, p, l0: F  # noqa: E731

    def full(F, p):
        return full3(F, p, jnp.nan)

    def W(F, p):
        return energy(full(F, p), p)

    def stress_state(F, p, l0):
        F3 = full3(F, p, l0)
        return jax.grad(energy)(F3, p)[:d, :d], F3[2, 2]

    def stress(F, p):
        return stress_state(F, p, jnp.nan)[0]

    def stress_and_tangent_state(F, p, l0):
        if kind == "plane-stress":
            # The condensed tangent is the derivative of the in-plane stress with the stretch
            # following F (its implicit custom_jvp): four forward directions through one Newton
            # solve for the stretch. Measured 2.6x faster on CPU than condensing the 9x9 Hessian
            # (a Schur complement), which XLA fuses badly, and equal to it to rounding.
            def f(G):
                P, l = stress_state(G, p, l0)
                return P, (P, l)

            A, (P, l) = jax.jacfwd(f, has_aux=True)(F)  # A[i, K, j, L]
            return P, jnp.moveaxis(A.reshape(d, d, d * d), -1, 0), l
        F3 = full3(F, p, l0)
        P3 = jax.grad(energy)(F3, p)
        H = jax.hessian(energy)(F3, p)  # H[i, K, j, L] = d2 psi / dF_iK dF_jL
        A = H[:d, :d, :d, :d]
        # A[m] = dP/dF_m with m the flattened (j, L): symmetric, so transpose by reshape
        return P3[:d, :d], A.reshape(d * d, d, d), F3[2, 2]

    def stress_and_tangent(F, p):
        return stress_and_tangent_state(F, p, jnp.nan)[:2]

    return Reduced(W, stress, stress_and_tangent, full, jax.jit(stress_state), jax.jit(stress_and_tangent_state))
