"""Saint Venant-Kirchhoff: linear elasticity written in the Green-Lagrange strain."""

import jax.numpy as jnp

from ._base import Material, lame


def saint_venant_kirchhoff_energy(F, p):
    """psi = lam/2 tr(E)^2 + mu tr(E^2) with E the Green-Lagrange strain."""
    mu, lam = lame(p["E"], p["nu"])
    Eg = 0.5 * (F.T @ F - jnp.eye(3))
    return 0.5 * lam * jnp.trace(Eg) ** 2 + mu * jnp.sum(Eg * Eg)


MATERIAL = Material("saint-venant-kirchhoff", saint_venant_kirchhoff_energy, rank=2)
