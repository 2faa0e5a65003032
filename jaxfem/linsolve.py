"""Sparse linear solvers behind one small interface, usable inside ``jax.jit``.

A solver is made for a :class:`~jaxfem.assembly.Pattern` and called as
``solver(values, rhs, arrays) -> x`` where ``values`` are the matrix entries on the pattern.
The matrices jaxfem hands over are symmetric (Dirichlet rows and columns are replaced by the
identity), so a symmetric factorisation is valid.

- ``"pardiso"``: Intel MKL PARDISO via pypardiso (host callback); fastest here from ~50k unknowns.
- ``"superlu"``: SciPy's SuperLU with a symmetric-mode ordering (host callback); always available.
- ``"klu"``: KLU via klujax, an XLA custom call (no callback); good for small systems.
- ``"cg"``: Jacobi-preconditioned conjugate gradients in pure JAX (runs on a GPU; iterative).
- ``"dense"``: LAPACK on the dense matrix, for toy sizes and tests only.
- ``"auto"``: measured choice (see ``benchmarks/forward.py``): PARDISO where installed and the
  system has more than 50k unknowns, else SuperLU.
"""

from __future__ import annotations

import hashlib
import importlib.util
from typing import Callable

import jax
import jax.numpy as jnp
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .assembly import Pattern, matvec

AUTO_PARDISO_MIN_DOFS = 50_000


def available() -> list[str]:
    """Names of the solvers that work on this machine."""
    names = ["superlu", "cg", "dense"]
    if importlib.util.find_spec("pypardiso") is not None:
        names.insert(0, "pardiso")
    if importlib.util.find_spec("klujax") is not None:
        names.insert(1, "klu")
    return names


def _host_callback(host_solve: Callable, vals, rhs):
    out = jax.ShapeDtypeStruct(rhs.shape, rhs.dtype)
    return jax.pure_callback(host_solve, out, vals, rhs, vmap_method="sequential")


def _csr(pattern: Pattern, vals) -> sp.csr_matrix:
    n = pattern.n_dofs
    return sp.csr_matrix((np.asarray(vals, dtype=np.float64), pattern.cols, pattern.indptr), shape=(n, n))


class _FactorCache:
    """Keeps the last factorisation, keyed by a hash of the matrix values: repeated solves with
    the same tangent (tangent and adjoint solves after Newton, a Jacobian's many directions) cost
    one factorisation and many cheap triangular solves."""

    def __init__(self, factor: Callable):
        self.factor = factor
        self.key = None
        self.solve = None

    def __call__(self, vals, rhs):
        v = np.ascontiguousarray(vals)
        key = hashlib.blake2b(v.view(np.uint8), digest_size=16).digest()
        if key != self.key:
            self.key, self.solve = None, None
            self.solve = self.factor(v)
            self.key = key
        return self.solve(np.asarray(rhs, dtype=np.float64))


def superlu(pattern: Pattern) -> Callable:
    """SuperLU (scipy) with a symmetric ordering and diagonal pivoting preference."""

    def factor(vals):
        A = _csr(pattern, vals).tocsc()
        try:
            return spla.splu(A, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                             options={"SymmetricMode": True}).solve
        except RuntimeError:  # exactly singular
            return lambda b: np.full(b.shape, np.nan)

    cache = _FactorCache(factor)
    return lambda vals, rhs, arrays: _host_callback(cache, vals, rhs)


def pardiso(pattern: Pattern) -> Callable:
    """MKL PARDISO (pypardiso), real symmetric indefinite mode on the upper triangle."""
    import pypardiso

    upper = np.flatnonzero(pattern.cols >= pattern.rows)
    r, c = pattern.rows[upper], pattern.cols[upper]
    indptr = np.zeros(pattern.n_dofs + 1, np.int64)
    np.add.at(indptr, r + 1, 1)
    indptr = np.cumsum(indptr)
    n = pattern.n_dofs

    holder = {}

    def make():
        # Constructing a PyPardisoSolver searches the environment for MKL's runtime (0.6 s with a
        # large site-packages): make one per pattern and refactorise it.
        solver = pypardiso.PyPardisoSolver(mtype=-2)
        solver.set_iparm(1, 1)  # use the parameters below rather than MKL defaults
        solver.set_iparm(2, 2)  # nested dissection (METIS) ordering
        solver.set_iparm(10, 8)  # pivot perturbation 1e-8
        solver.set_iparm(11, 0)  # no scaling (symmetric indefinite default would need weighted matching)
        solver.set_iparm(13, 0)
        return solver

    def factor(vals):
        A = sp.csr_matrix((np.asarray(vals)[upper], c, indptr), shape=(n, n))
        A.has_sorted_indices = True
        solver = holder.get("solver") or holder.setdefault("solver", make())
        try:
            solver.factorize(A)
        except Exception:  # noqa: BLE001 - pardiso reports a singular matrix as a generic error
            return lambda b: np.full(b.shape, np.nan)

        def solve(b):
            try:
                return solver.solve(A, b)
            except Exception:  # noqa: BLE001
                return np.full(b.shape, np.nan)

        return solve

    cache = _FactorCache(factor)
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


SOLVERS = {"pardiso": pardiso, "superlu": superlu, "klu": klu, "cg": cg, "dense": dense}


def make_linear_solver(name: str, pattern: Pattern) -> tuple[str, Callable]:
    """The solver called ``name`` (or the ``"auto"`` choice) for ``pattern``; returns (name, solve)."""
    if name == "auto":
        big = pattern.n_dofs > AUTO_PARDISO_MIN_DOFS
        name = "pardiso" if big and "pardiso" in available() else "superlu"
    if name not in SOLVERS:
        raise ValueError(f"unknown linear solver {name!r}; known: {', '.join(SOLVERS)}, auto")
    if name not in available():
        raise ValueError(f"linear solver {name!r} is not installed here; available: {', '.join(available())}")
    return name, SOLVERS[name](pattern)
