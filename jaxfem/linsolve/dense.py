"""LAPACK on the dense matrix, for toy sizes and tests only."""

from __future__ import annotations

import jax.numpy as jnp

from ._base import LinearSolver


class Dense(LinearSolver):
    """Dense LU; only for toy problems (memory grows with n^2)."""

    name = "dense"
    rank = 5

    def __call__(self, values, rhs, arrays):
        n = rhs.shape[0]
        A = jnp.zeros((n, n), values.dtype).at[arrays["rows"], arrays["cols"]].add(values)
        return jnp.linalg.solve(A, rhs)
