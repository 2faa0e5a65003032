"""Material laws, one per module of this package, each written once as a strain-energy density
psi(F; params) of the 3x3 deformation gradient. Stresses and tangents come from JAX
differentiation of these formulas, never by hand.

Parameters are per-cell scalars (``E``, ``nu`` and any extra a law needs) so that a region, a set
of regions and a whole modulus field are the same code. Units: E in the user's stress unit, the
energy density in stress units (energy per reference volume).

To add a law, add one module here that defines its energy and ``MATERIAL = Material(...)`` (name,
energy, extra parameters with defaults and fit bounds, ``finite``, ``rank``, ``counterpart``):
:data:`LAWS` discovers it, the bundle accepts its name, a diagnosis tries it as an alternative
(:func:`alternatives`) and tests/test_registries.py sweeps it. Nothing else changes.
"""

from __future__ import annotations

import importlib
import pkgutil

from ..exceptions import ProblemError
from ._base import Material, Parameter, lame
from ._mixture import mixture, share


def _discover() -> dict[str, Material]:
    """Every public module's ``MATERIAL``, ordered by rank (then name)."""
    found = []
    for info in pkgutil.iter_modules(__path__):
        if not info.name.startswith("_"):
            found.append(importlib.import_module(f"{__name__}.{info.name}").MATERIAL)
    return {m.name: m for m in sorted(found, key=lambda m: (m.rank, m.name))}


#: law name (as in the bundle spec) -> :class:`Material`, in rank order
LAWS: dict[str, Material] = _discover()


def get_material(law: str | Material) -> Material:
    """The material called ``law`` (names as in the bundle spec), or ``law`` itself."""
    if isinstance(law, Material):
        return law
    key = law.lower().replace("_", "-").replace(" ", "-")
    if key not in LAWS:
        raise ProblemError(f"unknown material law {law!r}; use one of {', '.join(LAWS)}, "
                           "or pass a jaxfem.Material of your own")
    return LAWS[key]


def alternatives(law: str | Material) -> tuple[str, ...]:
    """The registered laws a diagnosis tries instead of ``law``, in the order it tries them.

    A finite-strain law's alternatives are the other finite-strain laws in rank order; a
    small-strain law's is its finite-strain ``counterpart`` alone (a small-strain model that
    misfits is first asked whether finite strain explains it).
    """
    m = get_material(law)
    if not m.finite:
        return (m.counterpart,) if m.counterpart else ()
    return tuple(name for name, other in LAWS.items() if other.finite and name != m.name)


__all__ = ["LAWS", "Material", "Parameter", "alternatives", "get_material", "lame", "mixture", "share"]
