"""Small-strain linear elasticity: the limit the other laws reduce to."""

import jax.numpy as jnp

from ._base import Material, lame


def linear_elastic_energy(F, p):
    """psi = lam/2 tr(eps)^2 + mu tr(eps^2), eps = sym(F) - I.

    Not frame invariant: valid for small displacements and rotations only.
    """
    mu, lam = lame(p["E"], p["nu"])
    eps = 0.5 * (F + F.T) - jnp.eye(3)
    return 0.5 * lam * jnp.trace(eps) ** 2 + mu * jnp.sum(eps * eps)


MATERIAL = Material("linear-elastic", linear_elastic_energy, finite=False, rank=3,
                    counterpart="neo-hookean")
