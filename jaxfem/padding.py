"""Padded sizes, so that one compiled program serves many meshes.

A compiled solve depends on the shapes of its arrays (cells, dofs, matrix entries, prescribed
dofs, traction-loaded facets), not on their values, once the mesh's index arrays are arguments of
the program rather than constants in it. Rounding each size up to a *bucket* (a few sizes per doubling) lets every mesh
of about the same size (the hypotheses, remeshes and models of one diagnosis) reuse one program.

What the padding adds does nothing:

- padding cells join the first node with themselves and carry a zero ``cell_mask``: their
  reference Jacobian is replaced by the identity and their volume by zero, so they add no
  energy, force or stiffness (their deformation gradient is the identity);
- padding dofs belong to no cell; they are neither free nor prescribed by the caller, and their
  rows and columns of the matrix are the identity (a diagonal entry each, added to the pattern
  after its real entries), so their displacement stays zero;
- padding prescribed dofs are distinct padding dofs held at zero;
- padding matrix entries are zeros between padding dofs, each at a place of its own (KLU refuses
  repeated entries), in a block that no real dof touches;
- padding traction facets are copies of the first real facet with a zero ``facet_mask``, which
  multiplies every facet's load: they add no force and no derivative, whatever the traction
  (a per-facet one is padded with zeros, a uniform ``(dim,)`` one is masked), and being real
  facets they have a nonzero area (a degenerate facet's area derivative would be NaN, and
  0 x NaN is NaN). A problem without traction facets keeps none (the force skips them).

The real entries come first in every padded array, so slicing recovers them.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import jax
import jax.numpy as jnp
import numpy as np

from .assembly import Pattern
from .exceptions import ProblemError

#: bucket sizes per doubling: the padding wastes at most 2^(1/4) - 1 = 19 % (about 9 % on average)
PER_DOUBLING = 4
#: the smallest bucket
MIN_BUCKET = 16


def bucket(n: int, per_doubling: int = PER_DOUBLING) -> int:
    """The smallest bucket size ``>= n``: ``ceil(2^(j / per_doubling))`` for an integer j, at
    least :data:`MIN_BUCKET`."""
    if n <= MIN_BUCKET:
        return MIN_BUCKET
    j = int(np.ceil(per_doubling * np.log2(n)))
    while int(np.ceil(2.0 ** ((j - 1) / per_doubling))) >= n:
        j -= 1
    while int(np.ceil(2.0 ** (j / per_doubling))) < n:
        j += 1
    return int(np.ceil(2.0 ** (j / per_doubling)))


@dataclass(frozen=True)
class Sizes:
    """Real and padded sizes of one problem (``*_p``: padded; all counts; ``n_facets``: the
    traction-loaded facets, 0 for a problem without)."""

    n_cells: int
    n_nodes: int
    dim: int
    nnz: int
    n_fixed: int
    n_cells_p: int
    n_nodes_p: int
    nnz_p: int
    n_fixed_p: int
    n_facets: int = 0
    n_facets_p: int = 0

    @property
    def n_dofs(self) -> int:
        return self.n_nodes * self.dim

    @property
    def n_dofs_p(self) -> int:
        return self.n_nodes_p * self.dim


def sizes(n_cells: int, n_nodes: int, dim: int, nnz: int, n_fixed: int, pad: bool = True,
          n_facets: int = 0) -> Sizes:
    """The padded sizes (``pad=False``: the real ones). Enough padding dofs are kept for the
    padding prescribed dofs, and at least one; ``n_facets`` traction facets go to their bucket
    (none stay none)."""
    if not pad:
        return Sizes(n_cells, n_nodes, dim, nnz, n_fixed, n_cells, n_nodes, nnz, n_fixed, n_facets, n_facets)
    n_fixed_p = bucket(n_fixed)
    extra_nodes = -(-(n_fixed_p - n_fixed) // dim) + 1
    n_nodes_p = bucket(n_nodes + extra_nodes)
    while True:  # enough padding dofs for the padding entries to have places of their own
        pad = (n_nodes_p - n_nodes) * dim
        nnz_p = bucket(nnz + pad)
        if pad * (pad - 1) >= nnz_p - nnz - pad:
            break
        n_nodes_p = bucket(n_nodes_p + 1)
    return Sizes(n_cells, n_nodes, dim, nnz, n_fixed, bucket(n_cells), n_nodes_p, nnz_p, n_fixed_p,
                 n_facets, bucket(n_facets) if n_facets else 0)


def fits(real: Sizes, into: Sizes) -> bool:
    """Whether a problem of ``real``'s real sizes can be padded to ``into``'s padded sizes (of
    the same dimension): every padded count at least the real one, padding dofs for the padding
    prescribed dofs (and at least one), room among them for the padding matrix entries, each
    at a place of its own (:func:`padded_arrays`), and traction facets where the problem has some
    (none where it has none)."""
    pad = (into.n_nodes_p - real.n_nodes) * real.dim
    extra = into.nnz_p - real.nnz - pad
    return (into.dim == real.dim and into.n_cells_p >= real.n_cells and pad >= 1
            and into.n_fixed_p - real.n_fixed <= pad and into.n_fixed_p >= real.n_fixed and extra >= 0
            and pad * (pad - 1) >= extra and into.n_facets_p >= real.n_facets
            and (into.n_facets_p == 0) == (real.n_facets == 0))


def with_headroom(own: Sizes, headroom: float) -> Sizes:
    """``own``'s real sizes padded as for a problem ``headroom`` times larger in every count
    (its own padding where that would not hold it, or ``headroom <= 1``)."""
    if headroom <= 1.0:
        return own
    up = lambda n: int(np.ceil(headroom * n))  # noqa: E731
    room = sizes(up(own.n_cells), up(own.n_nodes), own.dim, up(own.nnz), up(own.n_fixed), n_facets=up(own.n_facets))
    return padded_to(own, room) if fits(own, room) else own


def with_facets_of(into: Sizes, real: Sizes) -> Sizes:
    """``into``'s padded sizes with ``real``'s padded facet count where ``into``'s facets do not
    hold ``real``'s (too few, or some where it has none, or none where it has some)."""
    if into.n_facets_p >= real.n_facets and (into.n_facets_p == 0) == (real.n_facets == 0):
        return into
    return replace(into, n_facets_p=real.n_facets_p)


def padded_to(real: Sizes, into: Sizes) -> Sizes:
    """``real``'s real sizes with ``into``'s padded ones (:func:`fits` must hold)."""
    return Sizes(real.n_cells, real.n_nodes, real.dim, real.nnz, real.n_fixed, into.n_cells_p, into.n_nodes_p,
                 into.nnz_p, into.n_fixed_p, real.n_facets, into.n_facets_p)


def padded_arrays(s: Sizes, cells: np.ndarray, pattern: Pattern, fixed: np.ndarray, free: np.ndarray,
                  facets: np.ndarray | None = None) -> dict:
    """The solver's index and mask arrays at the padded sizes (host numpy; see the module doc).

    Args:
        cells: ``(n_cells, n_per_cell)``; pattern: the real mesh's pattern; fixed: the prescribed
        dofs ``(n_fixed,)`` (sorted); free: ``(n_dofs,)`` bool; facets: the traction facets
        ``(n_facets, k)`` (None: no ``tfacets`` nor ``facet_mask`` in the result).
    Returns:
        a dict like :attr:`Solver.arrays` (``cells``, ``edofs``, ``slots``, ``rows``, ``cols``,
        ``diag``, ``fixed``, ``free``, ``keep``, ``diag_fixed``, ``tfacets``) plus ``cell_mask``
        and ``facet_mask`` ``(n_facets_p,)``.
    """
    n, n_p, nnz, nnz_p = s.n_dofs, s.n_dofs_p, s.nnz, s.nnz_p
    pad_dofs = np.arange(n, n_p)
    extra = nnz_p - nnz - len(pad_dofs)
    half = -(-extra // 2)
    i, j = _first_pairs(len(pad_dofs), half)
    fill_r = np.stack([i, j], 1).ravel()[:extra] + n  # (i, j) then (j, i): a pattern of its own
    fill_c = np.stack([j, i], 1).ravel()[:extra] + n
    rows = np.concatenate([pattern.rows, pad_dofs, fill_r]).astype(np.int32)
    cols = np.concatenate([pattern.cols, pad_dofs, fill_c]).astype(np.int32)
    diag = np.concatenate([pattern.diag, nnz + np.arange(len(pad_dofs))]).astype(np.int32)
    free_p = np.zeros(n_p, bool)
    free_p[:n] = free
    keep = np.zeros(nnz_p)
    keep[:nnz] = free[pattern.rows] & free[pattern.cols]
    diag_fixed = np.zeros(nnz_p)
    diag_fixed[diag[~free_p]] = 1.0
    n_pad_cells = s.n_cells_p - s.n_cells
    k = pattern.edofs.shape[1]
    cells_p = np.concatenate([cells, np.zeros((n_pad_cells, cells.shape[1]), cells.dtype)]).astype(np.int32)
    # padding cells: every corner at node 0 (dofs 0 .. dim - 1)
    edofs = np.concatenate([pattern.edofs, np.tile(np.arange(k) % s.dim, (n_pad_cells, 1))]).astype(np.int32)
    slots = np.concatenate([pattern.slots, np.full(n_pad_cells * k * k, nnz)]).astype(np.int32)
    fixed_p = np.concatenate([fixed, pad_dofs[: s.n_fixed_p - s.n_fixed]]).astype(np.int32)
    mask = np.zeros(s.n_cells_p)
    mask[: s.n_cells] = 1.0
    out = {"cells": cells_p, "edofs": edofs, "slots": slots, "rows": rows, "cols": cols, "diag": diag,
           "fixed": fixed_p, "free": free_p.astype(np.float64), "keep": keep, "diag_fixed": diag_fixed,
           "cell_mask": mask}
    if facets is not None:
        out.update(padded_facets(s, facets))
    return out


def _first_pairs(m: int, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The first ``k`` pairs of ``np.triu_indices(m, 1)`` (row by row), without the other
    ``m (m - 1) / 2 - k`` (a padding of a few hundred dofs has tens of thousands)."""
    per_row = np.arange(m - 1, 0, -1)  # row r holds m - 1 - r pairs
    rows = int(np.searchsorted(np.cumsum(per_row), k)) + 1 if k > 0 else 0
    i = np.repeat(np.arange(rows), per_row[:rows])
    j = np.concatenate([np.arange(r + 1, m) for r in range(rows)]) if rows else np.zeros(0, int)
    return i[:k], j[:k]


def padded_facets(s: Sizes, facets: np.ndarray) -> dict:
    """``tfacets (n_facets_p, k)``: the traction ``facets (n_facets, k)`` and copies of the first
    (a real facet: a nonzero area, so finite derivatives), and ``facet_mask (n_facets_p,)``: 1 for
    a real facet, 0 for a copy (see the module doc)."""
    facets = np.asarray(facets)
    if len(facets) != s.n_facets:
        raise ProblemError(f"{len(facets)} traction facets, but the padded sizes were made for {s.n_facets}: "
                           "pass the problem's traction_facets with the sizes made for it")
    copies = np.repeat(facets[:1], s.n_facets_p - s.n_facets, axis=0)
    mask = np.zeros(s.n_facets_p)
    mask[: s.n_facets] = 1.0
    return {"tfacets": np.concatenate([facets, copies]).astype(np.int32), "facet_mask": mask}


def _is_cellwise(key: str, shape: tuple, s: Sizes) -> bool:
    return key not in ("X", "u_D", "f", "traction") and len(shape) >= 1 and shape[0] == s.n_cells


def pad_theta(theta: dict, s: Sizes, tangent: bool = False, axis: int = 0) -> dict:
    """Parameters (or, with ``tangent``, directions: zeros in the padding) at the padded sizes.

    Per-cell values repeat the last cell's (a valid material for the padding cells, which carry no
    volume); nodal coordinates and loads are padded with zeros, a per-facet ``traction``
    ``(n_facets, dim)`` too (a uniform ``(dim,)`` one is kept: the facet mask unloads the padding
    facets). ``axis`` is where the per-entry axis is (1 for a batch of directions with a leading
    axis). Traceable."""
    def pad(v, n_p, edge):
        xp = jnp if isinstance(v, jax.core.Tracer) else np  # concrete values: no device op to compile
        v = xp.asarray(v, dtype=np.float64)
        width = [(0, 0)] * v.ndim
        width[axis] = (0, n_p - v.shape[axis])
        return xp.pad(v, width, mode="edge" if edge and not tangent else "constant")

    out = {}
    for k, v in theta.items():
        if k == "X":
            out[k] = pad(v, s.n_nodes_p, False)
        elif k == "u_D":
            out[k] = pad(v, s.n_fixed_p, False)
        elif k == "f":
            out[k] = pad(v, s.n_dofs_p, False)
        elif k == "traction":
            out[k] = pad(v, s.n_facets_p, False) if np.ndim(v) - axis == 2 else v
        elif _is_cellwise(k, np.shape(v)[axis:], s):
            out[k] = pad(v, s.n_cells_p, True)
        else:
            out[k] = v
    return out


def unpad_theta(theta: dict, s: Sizes) -> dict:
    """The real entries of a padded parameter pytree (or of its cotangent)."""
    n = {"X": s.n_nodes, "u_D": s.n_fixed, "f": s.n_dofs}
    out = {}
    for k, v in theta.items():
        v = np.asarray(v)
        if k == "traction":
            out[k] = v[: s.n_facets] if v.ndim == 2 else v  # per facet, or one uniform (dim,)
        else:
            out[k] = v[: n.get(k, s.n_cells)]
    return out


#: directions are solved in batches of this many (one program for any number of them)
BATCH = 8


def pad_batch(tree, k: int, batch: int = BATCH):
    """A pytree of ``k`` directions (leading axis) padded with zeros to a multiple of ``batch``
    (host numpy)."""
    n = -(-k // batch) * batch
    return jax.tree.map(lambda v: np.pad(np.asarray(v, np.float64), [(0, n - k)] + [(0, 0)] * (np.ndim(v) - 1)), tree)
