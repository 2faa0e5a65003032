"""Jacobi-preconditioned conjugate gradients in pure JAX (runs on a GPU; iterative)."""

from __future__ import annotations

import jax

from ..assembly import Pattern, matvec
from ._base import LinearSolver


class CG(LinearSolver):
    """Jacobi-preconditioned conjugate gradients (pure JAX; for GPUs, SPD tangents only).

    Args:
        pattern: the sparsity pattern.
        tol: relative residual tolerance.
        maxiter: iteration limit (default ``10 n_dofs``).
    """

    name = "cg"
    rank = 4

    def __init__(self, pattern: Pattern, tol: float = 1e-12, maxiter: int | None = None):
        super().__init__(pattern)
        self.tol = tol
        self.maxiter = maxiter or 10 * pattern.n_dofs

    def program_key(self) -> tuple:
        return (type(self), self.tol, self.maxiter)

    def __call__(self, values, rhs, arrays):
        d = values[arrays["diag"]]
        A = lambda x: matvec(values, arrays["rows"], arrays["cols"], x)  # noqa: E731
        x, _ = jax.scipy.sparse.linalg.cg(A, rhs, tol=self.tol, maxiter=self.maxiter, M=lambda r: r / d)
        return x
