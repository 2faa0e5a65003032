"""Compressible Mooney-Rivlin on isochoric invariants, with the second invariant's share fitted."""

import jax.numpy as jnp

from .._small import det
from ._base import Material, Parameter, lame


def mooney_rivlin_energy(F, p):
    """psi = c10 (I1b - 3) + c01 (I2b - 3) + K/2 (ln J)^2.

    Parametrised so that its small-strain limit is linear elasticity with (E, nu):
    c10 + c01 = mu/2 and ``c01 = c01_fraction * mu/2`` (default 0.25), K = E / (3 (1 - 2 nu)).
    """
    mu, _ = lame(p["E"], p["nu"])
    K = p["E"] / (3.0 * (1.0 - 2.0 * p["nu"]))
    r = p.get("c01_fraction", 0.25)
    c10, c01 = (1.0 - r) * 0.5 * mu, r * 0.5 * mu
    J = det(F)
    C = F.T @ F
    I1 = jnp.trace(C)
    I2 = 0.5 * (I1**2 - jnp.sum(C * C))
    Jm23 = J ** (-2.0 / 3.0)
    return c10 * (Jm23 * I1 - 3.0) + c01 * (Jm23**2 * I2 - 3.0) + 0.5 * K * jnp.log(J) ** 2


MATERIAL = Material("mooney-rivlin", mooney_rivlin_energy, rank=1,
                    extra=(Parameter("c01_fraction", 0.25, 0.0, 0.95),))
