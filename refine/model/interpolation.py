"""The tracked points' interpolation and its derivatives on programs shared by every model of a
diagnosis (:meth:`refine.model.MeasuredModel.at_points_and_derivatives`, :meth:`~refine.model.
MeasuredModel.points_vjp`).

A model's probe (cells, shape-function weights, the cells a point may move into under a morph)
comes as arguments, padded to bucket sizes (:func:`jaxfem.padding.bucket`: nodes, cells, the
candidate cells per point), so that the models of one diagnosis
(its hypotheses, remeshes, the discretisation fits) compile these programs once per element and
bucket instead of once per model and number of frames (2-9 s each at load 3-10 when the probe's
arrays were constants of a program compiled per model), and once when two hypotheses fitted side
by side need one at the same time (:func:`jaxfem.program.compile_once`). What is compiled is the
points' weights on the (morphed) mesh and their derivatives; the frames are read with them on
the host (a product of weights and nodal values, linear in the values). The values are those of
:meth:`MeasuredModel.at_points` to rounding: padding nodes and cells are never looked up, and a
padding candidate cell repeats the point's own cell (the first of the tied candidates wins, as
before).
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
from jaxfem.padding import BATCH, bucket, pad_batch
from jaxfem.program import compile_once
from jaxfem.probe import Probe


def probe_arrays(probe: Probe, positions: np.ndarray, n_nodes: int, n_cells: int) -> dict:
    """The arguments of the shared programs for ``probe`` (of a mesh of ``n_nodes`` nodes and
    ``n_cells`` cells) at the points' ``positions (n_points, dim)``, padded (host numpy); with
    ``n_nodes_p``, the padded node count the nodal arrays must have."""
    out = {"cells": np.asarray(probe.cells), "nodes": np.asarray(probe.nodes), "weights": np.asarray(probe.weights),
           "positions": np.asarray(positions, np.float64)}
    if probe.neighbours is not None:
        nb = np.asarray(probe.neighbours)
        m = bucket(nb.shape[1])
        out["neighbours"] = np.concatenate([nb, np.repeat(nb[:, :1], m - nb.shape[1], axis=1)], axis=1)
        cells = np.asarray(probe.mesh_cells)
        out["mesh_cells"] = np.concatenate([cells, np.zeros((bucket(n_cells) - len(cells), cells.shape[1]),
                                                            cells.dtype)])
    return out, bucket(n_nodes)


def pad_nodes(a, n_nodes_p: int, axis: int = 0) -> np.ndarray:
    """``a`` with zero rows appended along ``axis`` up to ``n_nodes_p`` nodes (padding nodes are never looked up)."""
    a = np.asarray(a, np.float64)
    width = [(0, 0)] * a.ndim
    width[axis] = (0, n_nodes_p - a.shape[axis])
    return np.pad(a, width)


def _probe(X, arrays, moved: bool) -> Probe:
    """The probe at the reference nodes ``X (n_nodes_p, dim)`` (moved with them where ``moved``)."""
    probe = Probe(arrays["cells"], arrays["nodes"], arrays["weights"], arrays.get("neighbours"),
                  arrays.get("mesh_cells"))
    return probe.moved(X, arrays["positions"]) if moved else probe


@partial(jax.jit, static_argnames="moved")
def weights_jvp(X, dX, arrays, moved: bool):
    """Each point's nodes ``(n_points, k)`` and shape-function weights ``(n_points, k)`` on the
    mesh at ``X (n_nodes_p, dim)``, and the weights' derivatives along a batch of directions
    ``dX (b, n_nodes_p, dim)``, ``(b, n_points, k)`` (the nodes a point is read from are
    piecewise constant in X: a morph moves the weights)."""
    probe = _probe(X, arrays, moved)
    if not moved:
        return probe.nodes, probe.weights, jnp.zeros((dX.shape[0],) + probe.weights.shape)
    w = lambda XX: _probe(XX, arrays, moved).weights  # noqa: E731
    return probe.nodes, probe.weights, jax.vmap(lambda d: jax.jvp(w, (X,), (d,))[1])(dX)


def _weights(arrays, n_nodes_p, moved, X, dX):
    """:func:`weights_jvp` (compiled once per key whatever threads ask, :func:`compile_once`) on
    host arrays: ``(nodes, W, dW)`` as host numpy."""
    args = (pad_nodes(X, n_nodes_p), pad_nodes(dX, n_nodes_p, axis=1), arrays)
    compile_once(weights_jvp, *args, moved=moved)
    nodes, W, dW = weights_jvp(*args, moved=moved)
    return np.asarray(nodes), np.asarray(W), np.asarray(dW)


def points_and_derivatives(arrays, n_nodes_p, moved, U, dU, X, dX):
    """The nodal displacements ``U (n_frames, n_nodes, dim)`` at the points and their derivatives
    along ``k`` directions ``dU (k, n_frames, n_nodes, dim)``, ``dX (k, n_nodes, dim)``:
    ``(n_frames, n_points, dim)`` and ``(k, n_frames, n_points, dim)`` (host numpy). The weights
    and their derivatives once per batch of directions (:func:`weights_jvp`), then every frame
    by the product rule, ``d(W u) = dW u + W du``."""
    k = len(dU)
    dXp = pad_batch(np.asarray(dX, np.float64), k)
    parts = [_weights(arrays, n_nodes_p, moved, X, dXp[i: i + BATCH]) for i in range(0, len(dXp), BATCH)]
    nodes, W = parts[0][0], parts[0][1]
    dW = np.concatenate([p[2] for p in parts])[:k]
    at = np.asarray(U, np.float64)[:, nodes]  # (frames, points, k, dim)
    pred = np.einsum("pk,fpkd->fpd", W, at)
    der = np.einsum("ipk,fpkd->ifpd", dW, at) + np.einsum("pk,ifpkd->ifpd", W, np.asarray(dU, np.float64)[:, :, nodes])
    return pred, der


def points_pullback(arrays, n_nodes_p, moved, U, X, C):
    """The pull-back of the interpolation of ``U (n_frames, n_nodes, dim)`` (linear in U: the
    transposed weights) of the cotangents ``C (c, n_frames, n_points, dim)``: ``(c, n_frames,
    n_nodes, dim)`` (host numpy)."""
    U = np.asarray(U)
    nodes, W, _ = _weights(arrays, n_nodes_p, moved, X, np.zeros((BATCH,) + np.shape(X)))
    C = np.asarray(C, np.float64)
    out = np.zeros(C.shape[:2] + U.shape[1:])
    for i in range(len(C)):
        for f in range(C.shape[1]):
            np.add.at(out[i, f], nodes, W[..., None] * C[i, f][:, None, :])
    return out
