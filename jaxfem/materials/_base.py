"""What a material law is: :class:`Material` (its energy and parameters) and :func:`lame`."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

from .. import _config  # noqa: F401  (float64)


def lame(E, nu):
    """Lamé constants ``(mu, lam)`` from Young's modulus and Poisson's ratio (3D relations)."""
    mu = E / (2.0 * (1.0 + nu))
    lam = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
    return mu, lam


@dataclass(frozen=True)
class Parameter:
    """A parameter of a law beyond ``E`` and ``nu`` (dimensionless unless the law says otherwise).

    Attributes:
        name: its key in the parameter pytree (a per-cell scalar, like ``E``).
        default: its value when the caller gives none; also the start of a fit.
        lower, upper: the bounds a fit keeps it in.
        period: where the parameter is an angle defined modulo ``period`` (a fibre direction:
            pi), a fit starts from the best of a few values over one period (the misfit has a
            stationary point wherever the angle meets a symmetry of the loading); None otherwise.
        fit: False for a modelling choice (e.g. whether fibres carry compression): a law
            hypothesis holds it at its default instead of fitting it.
    """

    name: str
    default: float
    lower: float
    upper: float
    period: float | None = None
    fit: bool = True


@dataclass(frozen=True)
class Material:
    """A hyperelastic law: a name, its energy psi(F (3, 3), params) and its parameters.

    Attributes:
        name: the law's name as in the bundle spec (``"neo-hookean"``...).
        energy: ``psi(F, p) -> scalar`` with ``p`` a dict of scalars (``E``, ``nu``, extras).
        extra: the parameters beyond ``E`` and ``nu`` (:class:`Parameter`), in the order a fit
            takes them after ``nu``.
        finite: False for a small-strain law (no inversion check makes sense there).
        rank: the law's place in :data:`~jaxfem.materials.LAWS` and among the alternatives a
            diagnosis tries (:func:`~jaxfem.materials.alternatives`); lower comes first.
        counterpart: for a small-strain law, the finite-strain law whose limit it is (the one
            alternative a diagnosis tries for it); None for a finite-strain law.
        stiffness: ``C(p) -> (3, 3, 3, 3)``, the law's small-strain stiffness where it is not
            isotropic linear elasticity with (E, nu) (an anisotropic law's); None: it is.
    """

    name: str
    energy: Callable = field(repr=False)
    extra: tuple[Parameter, ...] = ()
    finite: bool = True
    rank: int = 100
    counterpart: str | None = None
    stiffness: Callable | None = field(default=None, repr=False)
