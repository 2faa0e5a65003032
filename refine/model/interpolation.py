"""The tracked points' displacements interpolated on a (morphed) mesh, and their derivatives, on
one compiled program shared by every model of about the same size.

A model's interpolation (:meth:`refine.model.MeasuredModel.at_points` on a mesh whose reference
nodes a geometry morph moves: each point's cell found again among its neighbours, its weights
recomputed) compiled once per model, with its probe arrays (the points' candidate cells, their
nodes, the points' positions) as constants in the program, would compile four to six times a
diagnosis (settle, the refit on every frame, the discretisation error's coarse mesh and sparser
drive, the hypotheses). Here those arrays are arguments, padded so that models of about
the same size share one program (:func:`points_and_derivatives`):

- nodes to the model's solver's padded node count (:mod:`jaxfem.padding`: the models that share
  a solve program share this one), cells likewise; padding nodes and cells are never looked up;
- the candidate cells per point to a bucket (:func:`jaxfem.padding.bucket`), padded with the
  point's own cell, which the first column already holds (ties go to the first: same choice);
- frames to at least :data:`MIN_FRAMES` and then a power of two (zero frames, sliced off): the
  search's frames and every frame of a short bundle share one program; the interpolation's cost
  is the morphed weights, computed once whatever the frames.

Every real value is the same as the per-model program's (each point's weights and each frame's
sum are computed alike; tests/test_shared_programs.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from jaxfem.executables import Kept
from jaxfem.padding import BATCH, bucket, pad_batch
from jaxfem.probe import Probe

#: frames are padded to at least this many (then to a power of two)
MIN_FRAMES = 4


@dataclass(frozen=True)
class PaddedProbe:
    """A probe's arrays padded for :func:`points_and_derivatives` (host numpy).

    Attributes:
        nodes: each point's cell's nodes, ``(n_points, k)``.
        neighbours: each point's candidate cells, its own first, ``(n_points, m_p)``.
        mesh_cells: every cell's nodes, padded with copies of the first cell, ``(n_cells_p, k)``.
        positions: the points' reference positions, ``(n_points, dim)``.
        n_nodes: the mesh's real node count; ``n_nodes_p`` the padded one.
    """

    nodes: np.ndarray
    neighbours: np.ndarray
    mesh_cells: np.ndarray
    positions: np.ndarray
    n_nodes: int
    n_nodes_p: int


def padded_probe(probe: Probe, positions, n_nodes: int, n_nodes_p: int, n_cells_p: int) -> PaddedProbe:
    """``probe`` (one with candidate cells, :func:`jaxfem.locate` on simplices) padded to
    ``n_nodes_p`` nodes and ``n_cells_p`` cells (at least the real counts)."""
    cells = np.asarray(probe.mesh_cells)
    nb = np.asarray(probe.neighbours)
    m_p = bucket(nb.shape[1])
    nb = np.concatenate([nb, np.repeat(nb[:, :1], m_p - nb.shape[1], axis=1)], axis=1)
    n_cells_p = max(n_cells_p, len(cells))
    cells = np.concatenate([cells, np.repeat(cells[:1], n_cells_p - len(cells), axis=0)])
    return PaddedProbe(np.asarray(probe.nodes), nb, cells, np.asarray(positions, float), n_nodes,
                       max(n_nodes_p, n_nodes))


def frames_padded(n: int) -> int:
    """The padded frame count: at least :data:`MIN_FRAMES`, then a power of two."""
    return max(MIN_FRAMES, 1 << int(np.ceil(np.log2(max(n, 1)))))


def _jvp_of(U, dU, X, dX, nodes, neighbours, mesh_cells, positions):
    """The points' displacements ``(frames, points, dim)`` and their derivatives along the
    directions ``dU (b, frames, nodes, dim)``, ``dX (b, nodes, dim)``: compiled once per shape."""
    probe = Probe(neighbours[:, 0], nodes, jnp.zeros(nodes.shape), neighbours, mesh_cells)

    def at(U, X):
        return jax.vmap(probe.moved(X, positions))(U)

    return at(U, X), jax.vmap(lambda a, b: jax.jvp(at, (U, X), (a, b))[1])(dU, dX)


def _at_of(U, X, nodes, neighbours, mesh_cells, positions):
    """The points' displacements ``(frames, points, dim)`` alone: compiled once per shape."""
    probe = Probe(neighbours[:, 0], nodes, jnp.zeros(nodes.shape), neighbours, mesh_cells)
    return jax.vmap(probe.moved(X, positions))(U)


# jitted, their executables kept on disk whole (jaxfem.executables: a later process neither traces
# nor lowers them)
_jvp = Kept(_jvp_of, "interpolation.jvp")
_at = Kept(_at_of, "interpolation.at")


def _pad_axis(a, n: int, axis: int) -> np.ndarray:
    a = np.asarray(a, float)
    if a.shape[axis] == n:
        return a
    width = [(0, 0)] * a.ndim
    width[axis] = (0, n - a.shape[axis])
    return np.pad(a, width)


def points_and_derivatives(pp: PaddedProbe, U, dU, X, dX):
    """The displacements ``U (n_frames, n_nodes, dim)`` at the points of ``pp`` on the mesh
    morphed to ``X (n_nodes, dim)``, ``(n_frames, n_points, dim)``, and their derivatives along
    ``k`` directions ``dU (k, n_frames, n_nodes, dim)``, ``dX (k, n_nodes, dim)``, ``(k,
    n_frames, n_points, dim)`` (host numpy), in batches of ``jaxfem.padding.BATCH``."""
    f, k = np.shape(U)[0], len(dU)
    f_p, n_p = frames_padded(f), pp.n_nodes_p
    U = _pad_axis(_pad_axis(U, f_p, 0), n_p, 1)
    X = _pad_axis(X, n_p, 0)
    dU = _pad_axis(_pad_axis(pad_batch(np.asarray(dU, float), k), f_p, 1), n_p, 2)
    dX = _pad_axis(pad_batch(np.asarray(dX, float), k), n_p, 1)
    arrays = (pp.nodes, pp.neighbours, pp.mesh_cells, pp.positions)
    out = [_jvp(U, dU[i: i + BATCH], X, dX[i: i + BATCH], *arrays) for i in range(0, len(dU), BATCH)]
    return np.asarray(out[0][0])[:f], np.concatenate([np.asarray(d) for _, d in out])[:k, :f]


def points(pp: PaddedProbe, U, X) -> jax.Array:
    """The displacements ``U (n_frames, n_nodes, dim)`` at the points of ``pp`` on the mesh
    morphed to ``X (n_nodes, dim)``, ``(n_frames, n_points, dim)``: the program's value, which on
    a morphed mesh may differ from the same operations run one by one (eagerly, as before) in
    the last digits (1e-14 relative on a smooth morph)."""
    f = np.shape(U)[0]
    U = _pad_axis(_pad_axis(U, frames_padded(f), 0), pp.n_nodes_p, 1)
    return _at(U, _pad_axis(X, pp.n_nodes_p, 0), pp.nodes, pp.neighbours, pp.mesh_cells, pp.positions)[:f]
