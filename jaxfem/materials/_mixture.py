"""A material that follows one of several laws cell by cell: a model whose known regions have
laws of their own (a stiff inclusion of another law than the sheet around it)."""

from __future__ import annotations

from ..exceptions import ProblemError
from ._base import Material, Parameter


def share(law: str) -> str:
    """The per-cell parameter that says how much of ``law`` a cell follows (1 or 0)."""
    return f"share:{law}"


def mixture(materials: tuple[Material, ...]) -> Material:
    """A :class:`Material` whose energy is ``sum_k share_k psi_k(F)``: law ``k`` on the cells
    whose parameter :func:`share` ``(law_k)`` is 1 (default: the first law everywhere).

    Args:
        materials: two or more distinct laws; their extra parameters are merged (a name two laws
            share is one parameter, with the first law's default and bounds).

    The energies of every law are evaluated on every cell (a law with share 0 costs its
    evaluation, not its contribution), so a mixture is slower than one law by about their number.
    """
    names = [m.name for m in materials]
    if len(materials) < 2 or len(set(names)) != len(names):
        raise ProblemError(f"a mixture needs two or more distinct laws, got {names}")
    extra = {}
    for m in materials:
        for q in m.extra:
            extra.setdefault(q.name, q)
    shares = tuple(Parameter(share(m.name), 1.0 if k == 0 else 0.0, 0.0, 1.0) for k, m in enumerate(materials))

    def energy(F, p):
        return sum(p[share(m.name)] * m.energy(F, p) for m in materials)

    return Material("+".join(names), energy, extra=tuple(extra.values()) + shares,
                    finite=all(m.finite for m in materials), rank=materials[0].rank)
