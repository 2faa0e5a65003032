"""Closed-form determinants and inverses of 2x2 and 3x3 matrices (batched over leading axes).

``jnp.linalg.det`` and ``inv`` go through an LU factorisation, which is many times slower than the
cofactor formulas for the tiny matrices at every quadrature point, and differentiates worse.
"""

import jax.numpy as jnp


def det(A):
    """Determinant of ``(..., 2, 2)`` or ``(..., 3, 3)`` matrices."""
    if A.shape[-1] == 2:
        return A[..., 0, 0] * A[..., 1, 1] - A[..., 0, 1] * A[..., 1, 0]
    return (A[..., 0, 0] * (A[..., 1, 1] * A[..., 2, 2] - A[..., 1, 2] * A[..., 2, 1])
            - A[..., 0, 1] * (A[..., 1, 0] * A[..., 2, 2] - A[..., 1, 2] * A[..., 2, 0])
            + A[..., 0, 2] * (A[..., 1, 0] * A[..., 2, 1] - A[..., 1, 1] * A[..., 2, 0]))


def inv(A):
    """Inverse of ``(..., 2, 2)`` or ``(..., 3, 3)`` matrices by cofactors."""
    d = det(A)[..., None, None]
    if A.shape[-1] == 2:
        adj = jnp.stack([jnp.stack([A[..., 1, 1], -A[..., 0, 1]], -1),
                         jnp.stack([-A[..., 1, 0], A[..., 0, 0]], -1)], -2)
        return adj / d
    r0, r1, r2 = A[..., 0, :], A[..., 1, :], A[..., 2, :]
    cols = jnp.stack([jnp.cross(r1, r2), jnp.cross(r2, r0), jnp.cross(r0, r1)], -1)
    return cols / d
