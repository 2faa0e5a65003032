"""The tracked points' interpolation and its derivatives on programs shared by every model of a
diagnosis (:meth:`refine.model.MeasuredModel.at_points_and_derivatives`, :meth:`~refine.model.
MeasuredModel.points_vjp`).

A model's probe (cells, shape-function weights, the cells a point may move into under a morph)
comes as arguments, padded to bucket sizes (:func:`jaxfem.padding.bucket`: nodes, cells, the
candidate cells per point), and the frames one at a time, so that the models of one diagnosis
(its hypotheses, remeshes, the discretisation fits) compile these programs once per element and
bucket instead of once per model and number of frames (2-9 s each at load 3-10 when the probe's
arrays were constants of a program compiled per model), and once when two hypotheses fitted side
by side need one at the same time (:func:`jaxfem.program.compile_once`). The values are those of
:meth:`MeasuredModel.at_points`: padding nodes and cells are never looked up, and a padding
candidate cell repeats the point's own cell (the first of the tied candidates wins, as before).
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


def _at(U, X, arrays, moved: bool):
    """One frame's nodal displacements ``U (n_nodes_p, dim)`` at the points, ``(n_points, dim)``."""
    probe = Probe(arrays["cells"], arrays["nodes"], arrays["weights"], arrays.get("neighbours"),
                  arrays.get("mesh_cells"))
    if moved:  # follow a geometry morph of the reference nodes
        probe = probe.moved(X, arrays["positions"])
    return probe(U)


@partial(jax.jit, static_argnames="moved")
def frame_jvp(U, dU, X, dX, arrays, moved: bool):
    """One frame at the points and its derivatives along a batch of directions ``dU, dX (b,
    n_nodes_p, dim)``: ``((n_points, dim), (b, n_points, dim))``."""
    at = lambda UU, XX: _at(UU, XX, arrays, moved)  # noqa: E731
    return at(U, X), jax.vmap(lambda a, b: jax.jvp(at, (U, X), (a, b))[1])(dU, dX)


@partial(jax.jit, static_argnames="moved")
def frame_vjp(U, X, C, arrays, moved: bool):
    """The pull-back of one frame's interpolation at ``U (n_nodes_p, dim)`` of a batch of
    cotangents ``C (b, n_points, dim)``: ``(b, n_nodes_p, dim)``."""
    _, pull = jax.vjp(lambda UU: _at(UU, X, arrays, moved), U)
    return jax.vmap(lambda c: pull(c)[0])(C)


def points_and_derivatives(arrays, n_nodes_p, moved, U, dU, X, dX):
    """:func:`frame_jvp` over every frame of ``U (n_frames, n_nodes, dim)`` and every batch of the
    ``k`` directions ``dU (k, n_frames, n_nodes, dim)``, ``dX (k, n_nodes, dim)``:
    ``(n_frames, n_points, dim)`` and ``(k, n_frames, n_points, dim)`` (host numpy)."""
    k = len(dU)
    Xp = pad_nodes(X, n_nodes_p)
    dUp, dXp = pad_batch(pad_nodes(dU, n_nodes_p, axis=2), k), pad_batch(pad_nodes(dX, n_nodes_p, axis=1), k)
    pred, der = [], []
    for f in range(len(U)):
        Uf = pad_nodes(U[f], n_nodes_p)
        compile_once(frame_jvp, Uf, dUp[:BATCH, f], Xp, dXp[:BATCH], arrays, moved=moved)
        out = [frame_jvp(Uf, dUp[i: i + BATCH, f], Xp, dXp[i: i + BATCH], arrays, moved=moved)
               for i in range(0, len(dUp), BATCH)]
        pred.append(np.asarray(out[0][0]))
        der.append(np.concatenate([np.asarray(d) for _, d in out])[:k])
    return np.stack(pred), np.stack(der, axis=1)


def points_pullback(arrays, n_nodes_p, moved, U, X, C):
    """:func:`frame_vjp` over every frame of ``U (n_frames, n_nodes, dim)`` for the cotangents
    ``C (c, n_frames, n_points, dim)``: ``(c, n_frames, n_nodes, dim)`` (host numpy)."""
    c, n_nodes = len(C), np.shape(U)[1]
    Xp, Cp = pad_nodes(X, n_nodes_p), pad_batch(np.asarray(C, np.float64), c)
    out = []
    for f in range(len(U)):
        Uf = pad_nodes(U[f], n_nodes_p)
        compile_once(frame_vjp, Uf, Xp, Cp[:BATCH, f], arrays, moved=moved)
        g = [np.asarray(frame_vjp(Uf, Xp, Cp[i: i + BATCH, f], arrays, moved=moved)) for i in range(0, len(Cp), BATCH)]
        out.append(np.concatenate(g)[:c, :n_nodes])
    return np.stack(out, axis=1)
