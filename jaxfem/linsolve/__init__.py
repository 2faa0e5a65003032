"""Sparse linear solvers behind one small interface (:class:`LinearSolver`), usable inside ``jax.jit``.

A solver is made for a :class:`~jaxfem.assembly.Pattern` and called as
``solver(values, rhs, arrays) -> x`` where ``values`` are the matrix entries on the pattern.
The matrices jaxfem hands over are symmetric (Dirichlet rows and columns are replaced by the
identity), so a symmetric factorisation is valid. One module per solver, registered by its name
in :data:`SOLVERS`:

- ``"pardiso"``: Intel MKL PARDISO (pypardiso), symbolic analysis once per pattern.
- ``"superlu"``: SciPy's SuperLU with a symmetric-mode ordering; always available.
- ``"cholmod"``: CHOLMOD (scikit-sparse, optional), symbolic analysis once per pattern; an
  indefinite tangent is still solved.
- ``"klu"``: KLU via klujax, an XLA custom call (no callback); good for small 2D systems.
- ``"cg"``: Jacobi-preconditioned conjugate gradients in pure JAX (runs on a GPU; iterative).
- ``"dense"``: LAPACK on the dense matrix, for toy sizes and tests only.
- ``"auto"``: the fastest by ``benchmarks/forward.py`` (benchmarks/measurements.md): PARDISO
  where installed; without it KLU for small 2D systems (< ``AUTO_KLU_MAX_DOFS_2D`` unknowns) and
  SuperLU otherwise (KLU's fill grows badly in 3D).

To add a solver, add one module here with a :class:`LinearSolver` subclass (a :class:`HostSolver`
if it factorises on the host) that sets ``name``, ``rank`` and ``requires``; nothing else changes.
"""

from __future__ import annotations

import importlib
import inspect
import pkgutil

from ..assembly import Pattern
from ..elements import ELEMENTS
from ..exceptions import OptionError
from ._base import HostSolver, LinearSolver
from .pardiso import PardisoHandle

AUTO_KLU_MAX_DOFS_2D = 8_000


def _discover() -> dict[str, type[LinearSolver]]:
    """Every :class:`LinearSolver` subclass defined in a public module of this package, by rank."""
    found = []
    for info in pkgutil.iter_modules(__path__):
        if info.name.startswith("_"):
            continue
        module = importlib.import_module(f"{__name__}.{info.name}")
        found += [c for _, c in inspect.getmembers(module, inspect.isclass)
                  if issubclass(c, LinearSolver) and c.__module__ == module.__name__ and not inspect.isabstract(c)]
    return {c.name: c for c in sorted(found, key=lambda c: (c.rank, c.name))}


#: solver name -> its :class:`LinearSolver` class, in rank order
SOLVERS: dict[str, type[LinearSolver]] = _discover()


def available() -> list[str]:
    """Names of the solvers that work on this machine."""
    return [name for name, cls in SOLVERS.items() if cls.installed()]


def auto_choice(n_dofs: int, dim: int) -> str:
    """The solver ``"auto"`` picks for ``n_dofs`` unknowns of a ``dim``-dimensional mesh."""
    have = available()
    if "pardiso" in have:
        return "pardiso"
    if dim == 2 and n_dofs < AUTO_KLU_MAX_DOFS_2D and "klu" in have:
        return "klu"
    return "superlu"


def make_linear_solver(name: str, pattern: Pattern, dim: int | None = None) -> tuple[str, LinearSolver]:
    """The solver called ``name`` (or the ``"auto"`` choice) for ``pattern``; returns (name, solver).

    ``dim`` (the mesh dimension, 2 or 3) informs the ``"auto"`` choice; by default it is read off
    the pattern's element dofs where that is unambiguous and taken as 3 otherwise."""
    if name == "auto":
        if dim is None:  # an element's dofs tell its dimension, but for 12: tri6 or tet4, taken as 2D
            dim = 2 if pattern.edofs.shape[1] in {e.n_nodes * 2 for e in ELEMENTS.values() if e.dim == 2} else 3
        name = auto_choice(pattern.n_dofs, dim)
    if name not in SOLVERS:
        raise OptionError(f"unknown linear solver {name!r}; use one of {', '.join(SOLVERS)} or 'auto'")
    if name not in available():
        raise OptionError(f"linear solver {name!r} is not installed here (it needs the {SOLVERS[name].requires!r} "
                          f"package); install it or use one of {', '.join(available())} or 'auto'")
    return name, SOLVERS[name](pattern)


__all__ = ["AUTO_KLU_MAX_DOFS_2D", "HostSolver", "LinearSolver", "PardisoHandle", "SOLVERS", "auto_choice",
           "available", "make_linear_solver"]
