"""Materials, each written once as a strain-energy density psi(F; params) of the 3x3 deformation
gradient. Stresses and tangents come from JAX differentiation of these formulas, never by hand.

Parameters are per-cell scalars (``E``, ``nu`` and any extra a law needs) so that a region, a set
of regions and a whole modulus field are the same code. Units: E in the user's stress unit, the
energy density in stress units (energy per reference volume).

To add a law, write its energy and wrap it in :class:`Material`; nothing else changes.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import jax.numpy as jnp

from . import _config  # noqa: F401  (float64)
from ._small import det


def lame(E, nu):
    """Lamé constants ``(mu, lam)`` from Young's modulus and Poisson's ratio (3D relations)."""
    mu = E / (2.0 * (1.0 + nu))
    lam = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
    return mu, lam


def neo_hookean_energy(F, p):
    """Compressible neo-Hookean, psi = mu/2 (I1 - 3) - mu ln J + lam/2 (ln J)^2 (the bundle spec's law)."""
    mu, lam = lame(p["E"], p["nu"])
    J = det(F)
    lnJ = jnp.log(J)
    return 0.5 * mu * (jnp.sum(F * F) - 3.0) - mu * lnJ + 0.5 * lam * lnJ**2


def saint_venant_kirchhoff_energy(F, p):
    """Saint Venant-Kirchhoff, psi = lam/2 tr(E)^2 + mu tr(E^2) with E the Green-Lagrange strain."""
    mu, lam = lame(p["E"], p["nu"])
    Eg = 0.5 * (F.T @ F - jnp.eye(3))
    return 0.5 * lam * jnp.trace(Eg) ** 2 + mu * jnp.sum(Eg * Eg)


def linear_elastic_energy(F, p):
    """Small-strain linear elasticity, psi = lam/2 tr(eps)^2 + mu tr(eps^2), eps = sym(F) - I.

    Not frame invariant: valid for small displacements and rotations only (the small-strain limit
    that the other laws reduce to).
    """
    mu, lam = lame(p["E"], p["nu"])
    eps = 0.5 * (F + F.T) - jnp.eye(3)
    return 0.5 * lam * jnp.trace(eps) ** 2 + mu * jnp.sum(eps * eps)


def mooney_rivlin_energy(F, p):
    """Compressible Mooney-Rivlin on isochoric invariants,
    psi = c10 (I1b - 3) + c01 (I2b - 3) + K/2 (ln J)^2.

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


@dataclass(frozen=True)
class Material:
    """A hyperelastic law: a name, its energy psi(F (3, 3), params) and its parameter defaults.

    Attributes:
        name: the law's name as in the bundle spec (``"neo-hookean"``...).
        energy: ``psi(F, p) -> scalar`` with ``p`` a dict of scalars (``E``, ``nu``, extras).
        extra: names and default values of parameters beyond ``E`` and ``nu``.
        finite: False for the small-strain law (no inversion check makes sense there).
    """

    name: str
    energy: Callable = field(repr=False)
    extra: dict = field(default_factory=dict)
    finite: bool = True


LAWS: dict[str, Material] = {
    "neo-hookean": Material("neo-hookean", neo_hookean_energy),
    "saint-venant-kirchhoff": Material("saint-venant-kirchhoff", saint_venant_kirchhoff_energy),
    "linear-elastic": Material("linear-elastic", linear_elastic_energy, finite=False),
    "mooney-rivlin": Material("mooney-rivlin", mooney_rivlin_energy, extra={"c01_fraction": 0.25}),
}


def get_material(law: str | Material) -> Material:
    """The material called ``law`` (names as in the bundle spec), or ``law`` itself."""
    if isinstance(law, Material):
        return law
    key = law.lower().replace("_", "-").replace(" ", "-")
    if key not in LAWS:
        raise ValueError(f"unknown material law {law!r}; known: {', '.join(LAWS)}")
    return LAWS[key]
