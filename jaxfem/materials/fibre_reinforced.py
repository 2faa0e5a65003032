"""A neo-Hookean matrix reinforced by fibres in the reference plane (the standard reinforcing model):
a laminate's plies, or collagen along the skin's Langer lines.

    psi = psi_NH(F; E, nu) + k E / 8 * [(1 - m) f(I4(theta) - 1) + m f(I4(-theta) - 1)]

with ``I4(theta) = |F a|^2`` the squared stretch of the fibre direction ``a = (cos theta, sin theta,
0)`` of the reference configuration (``theta`` in radians, from the x axis towards the y axis; a
direction is defined modulo pi), ``m`` the share of the fibre stiffness in a second family mirrored
about the x axis (0: one family; 1/2: two symmetric families at +-theta, an angle-ply laminate or
the two collagen families of Holzapfel-Gasser-Ogden), and ``f`` the fibre's energy in its strain
``x = I4 - 1``: ``x^2`` in tension, ``c x^2`` in compression (``c``: the share of the stiffness
fibres keep in compression; 1 for a laminate's carbon fibres, 0 for collagen, which buckles),
switched on over a ramp ``0 <= x <= 2 RAMP`` where the stiffness grows as a smoothstep. ``f`` is
convex and C3 (its second derivative is continuous and piecewise smooth), so Newton's tangent is
continuous through the switch; at ``x = 0`` the energy, its slope and the compression-side
curvature are those of ``c x^2``, so the reference state is stress free for any ``c``.

Small strain (why this model, not Holzapfel-Gasser-Ogden's exponential): with ``eps_aa`` the
strain along ``a``, ``I4 - 1 = 2 eps_aa`` and the fibre term is ``c k E / 2 eps_aa^2``: the
small-strain stiffness is isotropic linear elasticity with the matrix's ``E`` and ``nu`` (they keep
their meaning) plus ``c k E`` times ``a x a x a x a`` (per family, weighted by its share). A
unidirectional ply pulled along its fibres has ``E_L ~ (1 + k) E``, across them ``E``: ``k ~ E_L /
E_T - 1`` (about 10 for carbon/epoxy). The exponential of HGO adds a second fibre parameter that
small strains (a laminate's, < 1 %) cannot fix; the quadratic law is the linear transversely
isotropic material there and stays polyconvex-like at finite strain (convex in I4).
"""

import math

import jax.numpy as jnp

from .._small import det
from ._base import Material, Parameter, lame

RAMP = 0.01
"""Half the width (in fibre strain ``I4 - 1``) of the tension ramp: a fibre that keeps a share
``c < 1`` in compression reaches its full stiffness at ``I4 - 1 = 2 RAMP``; with ``c = 1`` the
ramp does nothing."""


def _twice_integrated_smoothstep(x):
    """``R(x)``: R = R' = R'' = 0 for x <= 0, R'' rising as a smoothstep to 1 at ``x = 2 RAMP``,
    then ``R'' = 1`` (R is C3)."""
    d = RAMP
    u = jnp.clip(x / (2.0 * d), 0.0, 1.0)
    t = jnp.maximum(x - 2.0 * d, 0.0)
    return d * d * (u**4 - 0.4 * u**5) + d * t + 0.5 * t * t


def fibre_energy(x, c):
    """The fibre's energy in its strain ``x = I4 - 1`` (dimensionless; times ``k E / 8``):
    ``c x^2 + 2 (1 - c) R(x)``, i.e. ``x^2`` well into tension and ``c x^2`` in compression."""
    return c * x * x + 2.0 * (1.0 - c) * _twice_integrated_smoothstep(x)


def _i4(F, theta, sign):
    a = jnp.stack([jnp.cos(theta), sign * jnp.sin(theta), jnp.zeros_like(theta)])
    Fa = F @ a
    return jnp.sum(Fa * Fa)


def fibre_reinforced_energy(F, p):
    """psi (stress units) of the 3x3 ``F`` and the per-cell parameters ``p`` (module docstring):
    ``E``, ``nu`` (the matrix's), ``fibre_angle`` (rad), ``fibre_stiffness`` (k, the fibres'
    small-strain stiffness over E), ``fibre_compression`` (c) and ``fibre_mirror`` (m)."""
    mu, lam = lame(p["E"], p["nu"])
    lnJ = jnp.log(det(F))
    matrix = 0.5 * mu * (jnp.sum(F * F) - 3.0) - mu * lnJ + 0.5 * lam * lnJ**2
    theta, c, m = p["fibre_angle"], p["fibre_compression"], p["fibre_mirror"]
    fibres = (1.0 - m) * fibre_energy(_i4(F, theta, 1.0) - 1.0, c) + m * fibre_energy(_i4(F, theta, -1.0) - 1.0, c)
    return matrix + 0.125 * p["fibre_stiffness"] * p["E"] * fibres


def small_strain_stiffness(p):
    """The stiffness at the reference state, ``C[i, J, k, L]`` (3, 3, 3, 3): isotropic linear
    elasticity with (E, nu) plus ``c k E`` per fibre family (weighted by its share) along it."""
    mu, lam = lame(p["E"], p["nu"])
    d = jnp.eye(3)
    iso = (lam * jnp.einsum("ij,kl->ijkl", d, d)
           + mu * (jnp.einsum("ik,jl->ijkl", d, d) + jnp.einsum("il,jk->ijkl", d, d)))
    theta, m = p["fibre_angle"], p["fibre_mirror"]
    out = iso
    for share, sign in ((1.0 - m, 1.0), (m, -1.0)):
        a = jnp.stack([jnp.cos(theta), sign * jnp.sin(theta), 0.0 * theta])
        out = out + share * p["fibre_compression"] * p["fibre_stiffness"] * p["E"] * jnp.einsum("i,j,k,l->ijkl", a, a, a, a)
    return out


MATERIAL = Material(
    "fibre-reinforced", fibre_reinforced_energy, rank=4, stiffness=small_strain_stiffness,
    extra=(Parameter("fibre_angle", 0.0, -math.pi, math.pi, period=math.pi),
           Parameter("fibre_stiffness", 1.0, 0.0, 100.0),
           # modelling choices, not fitted: how the fibres behave in compression, how many families
           Parameter("fibre_compression", 1.0, 0.0, 1.0, fit=False),
           Parameter("fibre_mirror", 0.0, 0.0, 1.0, fit=False)))
