"""CHOLMOD (scikit-sparse, optional: its pip install needs SuiteSparse's headers), host callback."""

from __future__ import annotations

import scipy.sparse as sp

from ._base import HostSolver
from .superlu import superlu_factor


class Cholmod(HostSolver):
    """CHOLMOD: symbolic analysis on the first matrix, numeric Cholesky after.

    The matrix is symmetric, so the pattern's CSR arrays are also its CSC arrays: no conversion.
    An indefinite matrix (from buckling or a softening law) is factorised as L D L^T where CHOLMOD
    chooses its simplicial mode, and by SuperLU where CHOLMOD refuses it (supernodal mode): not an
    error, the Newton iteration decides what an indefinite tangent means. Runs on its own thread
    (its fallback is SuperLU)."""

    name = "cholmod"
    rank = 0
    requires = "sksparse"
    one_thread = True

    def __init__(self, pattern):
        super().__init__(pattern)
        self._analysis = None

    def factor(self, values):
        from sksparse.cholmod import CholmodNotPositiveDefiniteError, analyze

        n = self.pattern.n_dofs
        A = sp.csc_matrix((values, self.pattern.cols, self.pattern.indptr), shape=(n, n))
        try:
            if self._analysis is None:
                self._analysis = analyze(A, mode="auto")
            self._analysis.cholesky_inplace(A)
        except CholmodNotPositiveDefiniteError:
            return superlu_factor(self.pattern, values)
        return self._analysis.solve_A
