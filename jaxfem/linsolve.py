"""Sparse linear solvers behind one small interface, usable inside ``jax.jit``.

A solver is made for a :class:`~jaxfem.assembly.Pattern` and called as
``solver(values, rhs, arrays) -> x`` where ``values`` are the matrix entries on the pattern.
The matrices jaxfem hands over are symmetric (Dirichlet rows and columns are replaced by the
identity), so a symmetric factorisation is valid.

- ``"pardiso"``: Intel MKL PARDISO (the MKL that pypardiso installs), host callback; symbolic
  analysis once per pattern, then only numeric factorisation and substitution per matrix.
- ``"superlu"``: SciPy's SuperLU with a symmetric-mode ordering (host callback); always available.
- ``"cholmod"``: CHOLMOD (scikit-sparse, optional: its pip install needs SuiteSparse's headers),
  host callback; symbolic analysis once per pattern, then a numeric factorisation per matrix
  (an indefinite tangent, from buckling or a softening law, is still solved). The fastest
  complete factorisation (analysis included) of small 2D systems measured here.
- ``"klu"``: KLU via klujax, an XLA custom call (no callback); good for small systems.
- ``"cg"``: Jacobi-preconditioned conjugate gradients in pure JAX (runs on a GPU; iterative).
- ``"dense"``: LAPACK on the dense matrix, for toy sizes and tests only.
- ``"auto"``: measured choice (see ``benchmarks/forward.py``): PARDISO where installed (with its
  analysis reused it was the fastest per Newton iteration at every size from 2k unknowns, 2D and
  3D; CHOLMOD's numeric factorisation is slower than PARDISO's once the analysis is reused:
  0.97 vs 0.42 ms at 2k, two-level); without it KLU for small 2D systems (< 8k unknowns) and SuperLU
  otherwise (KLU's fill grows badly in 3D).
"""

from __future__ import annotations

import ctypes
import importlib.util
import threading
import weakref
from concurrent.futures import ThreadPoolExecutor
from typing import Callable

import jax
import jax.numpy as jnp
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .assembly import Pattern, matvec

AUTO_KLU_MAX_DOFS_2D = 8_000


def available() -> list[str]:
    """Names of the solvers that work on this machine."""
    names = ["superlu", "cg", "dense"]
    if importlib.util.find_spec("pypardiso") is not None:
        names.insert(0, "pardiso")
    if importlib.util.find_spec("klujax") is not None:
        names.insert(1 if "pardiso" in names else 0, "klu")
    if importlib.util.find_spec("sksparse") is not None:
        names.insert(0, "cholmod")
    return names


def _host_callback(host_solve: Callable, vals, rhs):
    out = jax.ShapeDtypeStruct(rhs.shape, rhs.dtype)
    return jax.pure_callback(host_solve, out, vals, rhs, vmap_method="sequential")


def _csr(pattern: Pattern, vals) -> sp.csr_matrix:
    n = pattern.n_dofs
    return sp.csr_matrix((np.asarray(vals, dtype=np.float64), pattern.cols, pattern.indptr), shape=(n, n))


class _FactorCache:
    """Keeps the last factorisation and the matrix values it belongs to: repeated solves with the
    same tangent (tangent and adjoint solves after Newton, a Jacobian's many directions) cost one
    factorisation and many cheap triangular solves. Comparing the values costs one pass over them
    (cheaper than hashing them).

    With ``one_thread`` every call runs on a host thread of the cache's own. SciPy's SuperLU
    (1.17) leaks a factorisation that is freed on another thread than the one that made it (it
    tracks its allocations per thread), and XLA runs callbacks on whichever of its threads is
    free: a diagnosis leaked ~2.7 MB per factorisation until the kernel killed it at 24 GB. On one
    thread the memory stays flat (tests/test_linsolve_superlu.py); the hand-over costs some
    microseconds. A thread per cache (per solver), not one for all: two models solved side by
    side (the diagnosis fits hypotheses in parallel) factorise side by side."""

    def __init__(self, factor: Callable, one_thread: bool = False):
        self.factor = factor
        self.vals = None
        # XLA may run two callbacks of one program at once (independent solves, e.g. of a third
        # derivative): the cache and a solver's handle (PARDISO's) take one call at a time, or MKL
        # segfaults on the shared handle
        self._lock = threading.Lock()
        self._slot = [None]  # the solve of the last factorisation (a list: see the finaliser)
        self._thread = None
        if one_thread:  # the last factorisation is freed on its own thread too, then the thread ends
            self._thread = ThreadPoolExecutor(max_workers=1, thread_name_prefix="jaxfem-factor")
            weakref.finalize(self, _retire, self._slot, self._thread).atexit = False

    def __call__(self, vals, rhs):
        if self._thread is not None:
            return self._thread.submit(self._call, vals, rhs).result()
        with self._lock:
            return self._call(vals, rhs)

    def _call(self, vals, rhs):
        v = np.asarray(vals, dtype=np.float64)
        if not np.isfinite(v).all():
            # A state that does not solve has no factorisation; Newton reads NaN as a failed solve
            return np.full(np.shape(rhs), np.nan)
        if self.vals is None or not np.array_equal(v, self.vals):
            self.vals, self._slot[0] = None, None
            self._slot[0] = self.factor(v)
            self.vals = v.copy()
        return self._slot[0](np.asarray(rhs, dtype=np.float64))


def _retire(slot: list, thread: ThreadPoolExecutor) -> None:
    """Free the last factorisation on the thread that made it, then let that thread end."""
    try:
        thread.submit(slot.clear)
        thread.shutdown(wait=False)
    except RuntimeError:  # the interpreter is shutting down
        pass


def _superlu_factor(pattern: Pattern, vals) -> Callable:
    """SuperLU factorisation of the matrix with values ``vals``; its solve (NaN if singular)."""
    A = _csr(pattern, vals).tocsc()
    try:
        return spla.splu(A, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                         options={"SymmetricMode": True}).solve
    except RuntimeError:  # exactly singular
        return lambda b: np.full(b.shape, np.nan)


def superlu(pattern: Pattern) -> Callable:
    """SuperLU (scipy) with a symmetric ordering and diagonal pivoting preference."""
    cache = _FactorCache(lambda vals: _superlu_factor(pattern, vals), one_thread=True)
    return lambda vals, rhs, arrays: _host_callback(cache, vals, rhs)


def _mkl_pardiso():
    """MKL's ``pardiso`` entry point (ctypes), loaded once per process.

    The library is the MKL runtime that pypardiso depends on; constructing a ``PyPardisoSolver``
    searches the environment for it (0.6 s with a large site-packages), so it is done only once.
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
        indptr, indices: CSR structure of the upper triangle (sorted column indices), ``(n + 1,)``
            and ``(nnz_upper,)``.
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
        ip[23] = 1   # two-level parallel factorisation: measured on 2 cores, numeric factorisation
        #              0.42 vs 0.57 ms at 2k unknowns (2D), 6.9 vs 8.2 ms at 21k, 58 vs 68 ms at 102k
        ip[34] = 1   # zero-based indices
        self.analysed = False
        self.a = None
        self.factorisations = 0
        fn, pt, n = _mkl_pardiso(), self.pt, self.n
        weakref.finalize(self, PardisoHandle._release, fn, pt, self.iparm.copy(), n)

    def _call(self, phase, a, b=None, x=None):
        err = ctypes.c_int32(0)
        one, i32 = ctypes.c_int32(1), ctypes.c_int32
        ptr = lambda arr: None if arr is None else arr.ctypes.data  # noqa: E731
        _mkl_pardiso()(self.pt.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)), ctypes.byref(one),
                       ctypes.byref(i32(1)), ctypes.byref(i32(-2)), ctypes.byref(i32(phase)),
                       ctypes.byref(i32(self.n)), ptr(a), ptr(self.ia), ptr(self.ja), None,
                       ctypes.byref(i32(1)), ptr(self.iparm), ctypes.byref(i32(0)), ptr(b), ptr(x),
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
        """x with A x = b for the last factorised A; NaN if the substitution failed."""
        b = np.ascontiguousarray(b, dtype=np.float64)
        x = np.empty_like(b)
        if self._call(33, self.a, b, x) != 0:
            x[:] = np.nan
        return x


def pardiso(pattern: Pattern) -> Callable:
    """MKL PARDISO, real symmetric indefinite mode on the upper triangle, symbolic analysis once."""
    upper = np.flatnonzero(pattern.cols >= pattern.rows)
    indptr = np.zeros(pattern.n_dofs + 1, np.int64)
    np.add.at(indptr, pattern.rows[upper] + 1, 1)
    handle = PardisoHandle(np.cumsum(indptr), pattern.cols[upper])

    def factor(vals):
        if not handle.factor(vals[upper]):  # pardiso reports a singular matrix as an error code
            return lambda b: np.full(b.shape, np.nan)
        return handle.solve

    cache = _FactorCache(factor)
    solve = lambda vals, rhs, arrays: _host_callback(cache, vals, rhs)  # noqa: E731
    solve.handle = handle
    return solve


def cholmod(pattern: Pattern) -> Callable:
    """CHOLMOD (scikit-sparse): symbolic analysis on the first matrix, numeric Cholesky after.

    The matrix is symmetric, so the pattern's CSR arrays are also its CSC arrays: no conversion.
    An indefinite matrix is factorised as L D L^T where CHOLMOD chooses its simplicial mode, and
    by SuperLU where CHOLMOD refuses it (supernodal mode): not an error, the Newton iteration
    decides what an indefinite tangent means."""
    from sksparse.cholmod import CholmodNotPositiveDefiniteError, analyze

    n = pattern.n_dofs
    state = {"factor": None}

    def factor(vals):
        A = sp.csc_matrix((vals, pattern.cols, pattern.indptr), shape=(n, n))
        try:
            if state["factor"] is None:
                state["factor"] = analyze(A, mode="auto")
            state["factor"].cholesky_inplace(A)
        except CholmodNotPositiveDefiniteError:
            return _superlu_factor(pattern, vals)
        return state["factor"].solve_A

    cache = _FactorCache(factor, one_thread=True)  # its fallback is SuperLU
    return lambda vals, rhs, arrays: _host_callback(cache, vals, rhs)


def klu(pattern: Pattern) -> Callable:
    """KLU through klujax: an XLA custom call, no Python in the loop."""
    import klujax

    def solve(vals, rhs, arrays):
        return klujax.solve(arrays["rows"], arrays["cols"], vals, rhs)

    return solve


def cg(pattern: Pattern, tol: float = 1e-12, maxiter: int | None = None) -> Callable:
    """Jacobi-preconditioned conjugate gradients (pure JAX; for GPUs, SPD tangents only)."""
    maxiter = maxiter or 10 * pattern.n_dofs

    def solve(vals, rhs, arrays):
        d = vals[arrays["diag"]]
        A = lambda x: matvec(vals, arrays["rows"], arrays["cols"], x)  # noqa: E731
        x, _ = jax.scipy.sparse.linalg.cg(A, rhs, tol=tol, maxiter=maxiter, M=lambda r: r / d)
        return x

    return solve


def dense(pattern: Pattern) -> Callable:
    """Dense LU; only for toy problems (memory grows with n^2)."""

    def solve(vals, rhs, arrays):
        n = rhs.shape[0]
        A = jnp.zeros((n, n), vals.dtype).at[arrays["rows"], arrays["cols"]].add(vals)
        return jnp.linalg.solve(A, rhs)

    return solve


SOLVERS = {"pardiso": pardiso, "cholmod": cholmod, "superlu": superlu, "klu": klu, "cg": cg, "dense": dense}


def auto_choice(n_dofs: int, dim: int) -> str:
    """The solver ``"auto"`` picks for ``n_dofs`` unknowns of a ``dim``-dimensional mesh."""
    have = available()
    if "pardiso" in have:
        return "pardiso"
    if dim == 2 and n_dofs < AUTO_KLU_MAX_DOFS_2D and "klu" in have:
        return "klu"
    return "superlu"


def make_linear_solver(name: str, pattern: Pattern, dim: int | None = None) -> tuple[str, Callable]:
    """The solver called ``name`` (or the ``"auto"`` choice) for ``pattern``; returns (name, solve).

    ``dim`` (the mesh dimension, 2 or 3) informs the ``"auto"`` choice; by default it is read off
    the pattern's element dofs where that is unambiguous and taken as 3 otherwise."""
    if name == "auto":
        if dim is None:
            dim = 2 if pattern.edofs.shape[1] in (6, 8, 12) else 3  # tri3, quad4, tri6 in 2D
        name = auto_choice(pattern.n_dofs, dim)
    if name not in SOLVERS:
        raise ValueError(f"unknown linear solver {name!r}; known: {', '.join(SOLVERS)}, auto")
    if name not in available():
        raise ValueError(f"linear solver {name!r} is not installed here; available: {', '.join(available())}")
    return name, SOLVERS[name](pattern)
