"""Intel MKL PARDISO (the MKL that pypardiso installs), host callback: symbolic analysis once per
pattern, then only numeric factorisation and substitution per matrix."""

from __future__ import annotations

import ctypes
import weakref

import numpy as np

from ..assembly import Pattern
from ._base import HostSolver, nan_solve


def _mkl_pardiso():
    """MKL's ``pardiso`` entry point (ctypes), loaded once per process.

    The library is the MKL runtime that pypardiso depends on; constructing a ``PyPardisoSolver``
    searches the environment for it (slow with a large site-packages), so it is done only once.
    """
    global _PARDISO_FN
    if _PARDISO_FN is None:
        import pypardiso

        fn = pypardiso.PyPardisoSolver().libmkl.pardiso
        p_i32, p_void = ctypes.POINTER(ctypes.c_int32), ctypes.c_void_p
        fn.argtypes = [ctypes.POINTER(ctypes.c_int64), p_i32, p_i32, p_i32, p_i32, p_i32, p_void, p_void,
                       p_void, p_void, p_i32, p_void, p_i32, p_void, p_void, p_i32]
        fn.restype = None
        _PARDISO_FN = fn
    return _PARDISO_FN


_PARDISO_FN = None


class PardisoHandle:
    """One MKL PARDISO instance for one sparsity pattern (real symmetric indefinite, upper triangle).

    The symbolic analysis (fill-reducing METIS ordering, phase 11) depends only on the pattern,
    because scaling and weighted matching are off; it is done once, on the first matrix. Every
    later matrix costs a numeric factorisation (phase 22) and each right-hand side a forward and
    backward substitution (phase 33). Index arrays are zero-based int32 made once, so a call does
    no conversion. The factors live in MKL's memory and are released with the handle.

    Args:
        indptr: CSR structure of the upper triangle, ``(n + 1,)``.
        indices: its sorted column indices, ``(nnz_upper,)``.
    """

    def __init__(self, indptr, indices):
        self.n = len(indptr) - 1
        self.ia = np.ascontiguousarray(indptr, dtype=np.int32)
        self.ja = np.ascontiguousarray(indices, dtype=np.int32)
        self.pt = np.zeros(64, np.int64)
        self.iparm = np.zeros(64, np.int32)
        ip = self.iparm  # zero-based; the MKL manual numbers them from 1
        ip[0] = 1    # use the values below, not MKL's defaults
        ip[1] = 2    # nested dissection (METIS) ordering
        ip[9] = 8    # pivot perturbation 1e-8
        ip[10] = 0   # no scaling and
        ip[12] = 0   # no weighted matching: the analysis then depends on the pattern only
        ip[23] = 1   # two-level parallel factorisation (the faster one on 2 cores: HISTORY.md)
        ip[34] = 1   # zero-based indices
        self.analysed = False
        self.a = None
        self.factorisations = 0
        fn, pt, n = _mkl_pardiso(), self.pt, self.n
        weakref.finalize(self, PardisoHandle._release, fn, pt, self.iparm.copy(), n)

    def _call(self, phase, a, b=None, x=None, nrhs=1):
        err = ctypes.c_int32(0)
        one, i32 = ctypes.c_int32(1), ctypes.c_int32
        ptr = lambda arr: None if arr is None else arr.ctypes.data  # noqa: E731
        _mkl_pardiso()(self.pt.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)), ctypes.byref(one),
                       ctypes.byref(i32(1)), ctypes.byref(i32(-2)), ctypes.byref(i32(phase)),
                       ctypes.byref(i32(self.n)), ptr(a), ptr(self.ia), ptr(self.ja), None,
                       ctypes.byref(i32(nrhs)), ptr(self.iparm), ctypes.byref(i32(0)), ptr(b), ptr(x),
                       ctypes.byref(err))
        return err.value

    @staticmethod
    def _release(fn, pt, iparm, n):
        err, i32 = ctypes.c_int32(0), ctypes.c_int32
        fn(pt.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)), ctypes.byref(i32(1)), ctypes.byref(i32(1)),
           ctypes.byref(i32(-2)), ctypes.byref(i32(-1)), ctypes.byref(i32(n)), None, None, None, None,
           ctypes.byref(i32(1)), iparm.ctypes.data, ctypes.byref(i32(0)), None, None, ctypes.byref(err))

    def factor(self, a) -> bool:
        """Numeric factorisation of the matrix with upper-triangle values ``a``; False if it failed."""
        a = np.ascontiguousarray(a, dtype=np.float64)
        if not self.analysed:
            if self._call(11, a) != 0:
                return False
            self.analysed = True
        self.factorisations += 1
        self.a = a  # kept: the substitutions' iterative refinement reads the matrix
        return self._call(22, a) == 0

    def solve(self, b):
        """x with A x = b for the last factorised A, ``b (n,)`` or ``(n, k)`` (k right-hand sides
        in one call: blocked substitutions); NaN if the substitution failed."""
        b = np.asfortranarray(b, dtype=np.float64)  # PARDISO reads the right-hand sides column after column
        x = np.empty_like(b, order="F")
        if self._call(33, self.a, b, x, nrhs=1 if b.ndim == 1 else b.shape[1]) != 0:
            x[:] = np.nan
        return x


class Pardiso(HostSolver):
    """MKL PARDISO, real symmetric indefinite mode on the upper triangle, symbolic analysis once.

    ``handle`` is the solver's :class:`PardisoHandle` (it counts the numeric factorisations)."""

    name = "pardiso"
    rank = 1
    requires = "pypardiso"

    def __init__(self, pattern: Pattern):
        super().__init__(pattern)
        self._upper = np.flatnonzero(pattern.cols >= pattern.rows)
        indptr = np.zeros(pattern.n_dofs + 1, np.int64)
        np.add.at(indptr, pattern.rows[self._upper] + 1, 1)
        self.handle = PardisoHandle(np.cumsum(indptr), pattern.cols[self._upper])

    def factor(self, values):
        if not self.handle.factor(values[self._upper]):  # pardiso reports a singular matrix as an error code
            return nan_solve
        return self.handle.solve
