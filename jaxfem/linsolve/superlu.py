"""SciPy's SuperLU with a symmetric-mode ordering (host callback); always available."""

from __future__ import annotations

from typing import Callable

import scipy.sparse.linalg as spla

from ..assembly import Pattern
from ._base import HostSolver, csr, nan_solve


def superlu_factor(pattern: Pattern, vals) -> Callable:
    """SuperLU factorisation of the matrix with values ``vals``; its solve (NaN if singular)."""
    A = csr(pattern, vals).tocsc()
    try:
        return spla.splu(A, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                         options={"SymmetricMode": True}).solve
    except RuntimeError:  # exactly singular
        return nan_solve


class SuperLU(HostSolver):
    """SuperLU (scipy) with a symmetric ordering and diagonal pivoting preference.

    Every factorisation is made and freed on the solver's own thread (SciPy's SuperLU leaks one
    freed on another thread; see :class:`~jaxfem.linsolve._base._FactorCache`)."""

    name = "superlu"
    rank = 3
    one_thread = True

    def factor(self, values):
        return superlu_factor(self.pattern, values)
