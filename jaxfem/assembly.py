"""Assembly: element kinematics, residual vector and tangent values on a fixed sparsity pattern.

The pattern (which global matrix entries exist, and where each element entry lands) is computed
once per mesh on the host. Inside ``jit`` the tangent is a flat vector of values on that pattern,
summed with one scatter-add, so nothing is recompiled when parameter values change.

Element quantities are vectorised over cells; there is no Python loop over elements. The stress
and the material tangent at each quadrature point are the first and second derivatives of the
energy (by JAX); the element vectors and matrices are their contraction with the shape-function
gradients (the chain rule, nothing constitutive is written by hand).
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from . import _config  # noqa: F401
from ._small import det, inv
from .elements import Element, get_element
from .kinematics import Reduced
from .mesh import Mesh


# ====================================================================== host-side pattern
@dataclass(frozen=True, eq=False)
class Pattern:
    """Sparsity pattern of the global tangent and the scatter maps into it (host numpy arrays).

    Attributes:
        n_dofs: number of unknowns (nodes x dim), dof index = node * dim + component.
        edofs: global dofs of each cell, ``(n_cells, n_per_cell * dim)``.
        slots: for every element-matrix entry (cell-major, row-major) its index in ``values``.
        rows, cols: COO coordinates of the pattern entries, sorted by row then column (CSR order).
        indptr: CSR row pointer, ``(n_dofs + 1,)``.
        diag: index in ``values`` of each diagonal entry, ``(n_dofs,)``.
    """

    n_dofs: int
    edofs: np.ndarray
    slots: np.ndarray
    rows: np.ndarray
    cols: np.ndarray
    indptr: np.ndarray
    diag: np.ndarray

    @property
    def nnz(self) -> int:
        return len(self.rows)


def make_pattern(mesh: Mesh) -> Pattern:
    """Compute the tangent's sparsity pattern for ``mesh`` (once per mesh)."""
    dim = mesh.dim
    edofs = (mesh.cells[:, :, None] * dim + np.arange(dim)).reshape(mesh.n_cells, -1)
    k = edofs.shape[1]
    r = np.repeat(edofs, k, axis=1).ravel()
    c = np.tile(edofs, (1, k)).ravel()
    n = mesh.n_dofs
    key = r.astype(np.int64) * n + c
    uniq, slots = np.unique(key, return_inverse=True)
    rows, cols = uniq // n, uniq % n
    indptr = np.zeros(n + 1, np.int64)
    np.add.at(indptr, rows + 1, 1)
    indptr = np.cumsum(indptr)
    diag_key = np.arange(n, dtype=np.int64) * n + np.arange(n)
    diag = np.searchsorted(uniq, diag_key)
    return Pattern(n, edofs.astype(np.int32), slots.astype(np.int32).ravel(), rows.astype(np.int32),
                   cols.astype(np.int32), indptr, diag.astype(np.int32))


# ====================================================================== element kinematics
def shape_gradients(X, cells, el: Element, mask=None):
    """Reference-configuration shape gradients and integration weights.

    Args:
        X: nodal reference coordinates ``(n_nodes, dim)`` (differentiable).
        cells: ``(n_cells, n_per_cell)``.
        mask: optional ``(n_cells,)``, 1 for a cell and 0 for a padding cell (:mod:`jaxfem.padding`),
            whose reference Jacobian is taken as the identity and whose volume as zero.
    Returns:
        ``dNdX (n_cells, n_qp, n_per_cell, dim)`` and ``dV (n_cells, n_qp)``: quadrature weight
        times Jacobian determinant (reference area or volume per point).
    """
    Xe = X[cells]
    J0 = jnp.einsum("cki,qkj->cqij", Xe, el.dN)
    if mask is not None:
        J0 = jnp.where(mask[:, None, None, None] > 0, J0, jnp.eye(J0.shape[-1]))
    dNdX = jnp.einsum("qkj,cqji->cqki", el.dN, inv(J0))
    dV = det(J0) * el.weights
    return dNdX, dV if mask is None else dV * mask[:, None]


def deformation_gradients(u, cells, dNdX):
    """F = I + grad u at every quadrature point, ``(n_cells, n_qp, dim, dim)``; ``u`` is ``(n_nodes, dim)``."""
    dim = u.shape[1]
    return jnp.eye(dim) + jnp.einsum("cki,cqkj->cqij", u[cells], dNdX)


def _per_qp(fn, F, p):
    """Apply ``fn(F, p)`` at each quadrature point; ``p`` holds per-cell scalars."""
    return jax.vmap(lambda Fc, pc: jax.vmap(lambda Fq: fn(Fq, pc))(Fc))(F, p)


def _per_qp_state(fn, F, p, state):
    """Apply ``fn(F, p, s)`` at each quadrature point with a per-point ``state (n_cells, n_qp)``;
    ``None`` is no state (NaN everywhere)."""
    if state is None:
        state = jnp.full(F.shape[:2], jnp.nan, F.dtype)
    return jax.vmap(lambda Fc, pc, sc: jax.vmap(lambda Fq, sq: fn(Fq, pc, sq))(Fc, sc))(F, p, state)


def _materialized(a):
    """The arrays ``a``, computed once into memory: every element-matrix term reads them, and XLA
    would otherwise fuse their whole computation into each read, recomputing it per term. On CPU an
    optimisation barrier does not stop that fusion; a conditional does (its predicate is never true
    for finite data, and either branch returns the same values)."""
    flag = jnp.isnan(jax.tree.leaves(a)[0].reshape(-1)[0])
    return jax.lax.cond(flag, lambda x: jax.tree.map(lambda y: y + 0.0, x), lambda x: x, a)


def element_matrices(dNdX, A, w):
    """Element tangent matrices ``Ke[c, a, i, b, j] = sum_q w dN_a/dX_K A[j, L, i, K] dN_b/dX_L``.

    Args:
        dNdX: ``(n_cells, n_qp, n_per_cell, dim)``; A: ``(n_cells, n_qp, dim, dim, dim, dim)`` with
        ``A[c, q, j, L, i, K] = dP_iK / dF_jL``; w: ``(n_cells, n_qp)``.

    With few terms (n_qp x dim^2 <= 16: tri3, tri6, quad4, tet4) the sum is written term by term
    with the cells on the minor axis, which XLA turns into one vectorised loop over the cells
    (several times faster than ``einsum`` there); ``einsum`` (batched small matrix products) stays
    for more terms (hex8: 72), where the term-by-term form is slower (benchmarks/measurements.md).
    """
    nq, dim = dNdX.shape[1], dNdX.shape[3]
    if nq * dim * dim > 16:
        return jnp.einsum("cqaK,cqjLiK,cqbL,cq->caibj", dNdX, A, dNdX, w)
    dNdX, A, w = _materialized((dNdX, A, w))
    dN, At, wt = jnp.moveaxis(dNdX, 0, -1), jnp.moveaxis(A, 0, -1), jnp.moveaxis(w, 0, -1)
    Ke = 0.0
    for q in range(nq):
        for K in range(dim):
            left = dN[q, :, K, None, None, None, :] * wt[q]                                  # a . . . c
            for L in range(dim):
                Aq = jnp.transpose(At[q, :, L, :, K, :], (1, 0, 2))[None, :, None, :, :]     # . i . j c
                Ke = Ke + left * Aq * dN[q, None, None, :, L, None, :]                        # a i b j c
    return jnp.moveaxis(Ke, -1, 0)


# ====================================================================== global quantities
@dataclass(frozen=True, eq=False)
class Assembler:
    """Global energy, residual and tangent of one mesh and one material law under one kinematics
    (a :class:`~jaxfem.kinematics.Reduced`).

    All methods are pure JAX functions of ``(u, X, p, t)``: displacements ``(n_nodes, dim)``,
    reference coordinates ``(n_nodes, dim)``, per-cell parameter dict ``p`` and per-cell
    thickness ``t`` (ones in 3D). Index arrays come from ``arrays`` (passed in, never closed over,
    so XLA does not constant-fold them).
    """

    element: str
    law: Reduced

    @property
    def el(self) -> Element:
        return get_element(self.element)

    def energy(self, u, X, p, t, cells):
        """Total strain energy (energy units: stress x volume)."""
        dNdX, dV = shape_gradients(X, cells, self.el)
        F = deformation_gradients(u, cells, dNdX)
        return jnp.sum(_per_qp(self.law.energy, F, p) * dV * t[:, None])

    def _forces(self, u, X, p, t, cells, state=None, mask=None):
        dNdX, dV = shape_gradients(X, cells, self.el, mask)
        F = deformation_gradients(u, cells, dNdX)
        P, state = _per_qp_state(self.law.stress_state, F, p, state)
        return jnp.einsum("cqiK,cqaK,cq->cai", P, dNdX, dV * t[:, None]).reshape(len(cells), -1), F, state

    def element_residuals(self, u, X, p, t, cells):
        """Internal nodal forces of each cell, ``(n_cells, n_per_cell * dim)``."""
        return self._forces(u, X, p, t, cells)[0]

    def residual(self, u, X, p, t, arrays):
        """Internal force vector, ``(n_dofs,)``."""
        Re = self._forces(u, X, p, t, arrays["cells"], mask=arrays.get("cell_mask"))[0]
        return jnp.zeros(u.size, u.dtype).at[arrays["edofs"].ravel()].add(Re.ravel())

    def residual_and_min_det(self, u, X, p, t, arrays, state=None):
        """Internal force vector, the smallest det F and the material state (one pass over the
        cells: what a Newton update needs to check the new state).

        ``state (n_cells, n_qp)`` is where the material's inner iteration starts (the out-of-plane
        stretch under plane stress; ``None``: its own estimate), and the state returned is where
        it converged, for the next call at a nearby ``u``."""
        Re, F, state = self._forces(u, X, p, t, arrays["cells"], state, arrays.get("cell_mask"))
        R = jnp.zeros(u.size, u.dtype).at[arrays["edofs"].ravel()].add(Re.ravel())
        return R, jnp.min(det(F)), state

    def residual_and_tangent(self, u, X, p, t, arrays, nnz: int | None = None, state=None):
        """Internal force vector ``(n_dofs,)``, tangent values on the pattern ``(nnz,)`` and the
        material state (see :meth:`residual_and_min_det`)."""
        cells = arrays["cells"]
        dNdX, dV = shape_gradients(X, cells, self.el, arrays.get("cell_mask"))
        F = deformation_gradients(u, cells, dNdX)
        P, A, state = _per_qp_state(self.law.stress_and_tangent_state, F, p, state)
        dim = u.shape[1]
        w = dV * t[:, None]
        Re = jnp.einsum("cqiK,cqaK,cq->cai", P, dNdX, w).reshape(len(cells), -1)
        A = A.reshape(A.shape[:2] + (dim, dim, dim, dim))  # (c, q, j, L, i, K) = dP_iK / dF_jL
        Ke = element_matrices(dNdX, A, w)
        R = jnp.zeros(u.size, u.dtype).at[arrays["edofs"].ravel()].add(Re.ravel())
        nnz = arrays["rows"].shape[0] if nnz is None else nnz
        vals = jnp.zeros(nnz, u.dtype).at[arrays["slots"]].add(Ke.ravel())
        return R, vals, state

    def min_jacobian(self, u, X, cells, mask=None):
        """Smallest det F over all quadrature points (<= 0 means an inverted element); ``mask``
        as in :func:`shape_gradients`."""
        dNdX, _ = shape_gradients(X, cells, self.el, mask)
        return jnp.min(det(deformation_gradients(u, cells, dNdX)))


def matvec(vals, rows, cols, x):
    """Sparse product ``K @ x`` with the pattern's COO coordinates."""
    return jnp.zeros_like(x).at[rows].add(vals * x[cols])


def facet_forces(X, facets, line_load, facet_element: str, n_dofs: int):
    """Nodal forces of dead loads on facets.

    Args:
        X: reference coordinates ``(n_nodes, dim)``.
        facets: facet node indices ``(n_facets, k)``.
        line_load: load per unit reference measure of each facet ``(n_facets, dim)``: in 2D force
            per unit length (traction x thickness), in 3D traction (force per area).
    Returns:
        ``(n_dofs,)`` nodal force vector.
    """
    fe = get_element(facet_element)
    Xf = X[facets]  # (f, k, dim)
    T = jnp.einsum("fki,qkj->fqij", Xf, fe.dN)  # tangents (f, q, dim, dim-1)
    if T.shape[-1] == 1:
        ds = jnp.linalg.norm(T[..., 0], axis=-1)
    else:
        ds = jnp.linalg.norm(jnp.cross(T[..., 0], T[..., 1]), axis=-1)
    w = ds * fe.weights  # (f, q)
    fa = jnp.einsum("qk,fq,fi->fki", fe.N, w, line_load)
    dim = X.shape[1]
    dofs = (facets[:, :, None] * dim + jnp.arange(dim)).ravel()
    return jnp.zeros(n_dofs, X.dtype).at[dofs].add(fa.ravel())
