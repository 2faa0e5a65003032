"""Compressible neo-Hookean: the bundle spec's law, and the one a diagnosis tries first."""

import jax.numpy as jnp

from .._small import det
from ._base import Material, lame


def neo_hookean_energy(F, p):
    """psi = mu/2 (I1 - 3) - mu ln J + lam/2 (ln J)^2."""
    mu, lam = lame(p["E"], p["nu"])
    J = det(F)
    lnJ = jnp.log(J)
    return 0.5 * mu * (jnp.sum(F * F) - 3.0) - mu * lnJ + 0.5 * lam * lnJ**2


MATERIAL = Material("neo-hookean", neo_hookean_energy, rank=0)
