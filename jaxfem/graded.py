"""Graded box meshes: fine where something is to be resolved, coarse elsewhere.

A graded box is :func:`jaxfem.mesh.box`'s brick lattice on node coordinates given per axis
(``ticks``): each brick maps affinely (a scaling per axis) to its place, so its six Kuhn
tetrahedra keep positive Jacobians and conform across bricks, and ``tet10``'s mid-edge nodes stay
at their edges' middles (straight edges). :func:`graded_ticks` makes one axis's ticks: spacing at
most ``fine`` over a focus interval, growing geometrically away from it up to ``coarse``.
"""

from __future__ import annotations

import numpy as np
from jaxtyping import Float

from .exceptions import MeshError
from .mesh import Mesh, box


def _outward(length: float, fine: float, coarse: float, growth: float) -> np.ndarray:
    """Spacings ``(n,)`` filling ``length`` from next to the focus outward: ``fine * growth^k``
    capped at ``coarse``, all scaled by one factor (at most 1) so that they sum to ``length``."""
    if length <= 1e-12 * max(fine, 1.0):
        return np.zeros(0)
    out, total, s = [], 0.0, fine
    while total < length * (1 - 1e-9):
        s = min(s * growth, coarse)
        out.append(s)
        total += s
    out = np.asarray(out)
    if len(out) > 1 and total - length > 0.5 * out[-1]:  # the last one mostly overshoots: drop it
        out = out[:-1]
    return out * (length / out.sum())


def graded_ticks(lo: float, hi: float, focus: tuple[float, float], fine: float, coarse: float,
                 growth: float = 1.5) -> Float[np.ndarray, "n"]:
    """The node coordinates ``(n,)`` of one axis of ``[lo, hi]`` (length unit), increasing, ``lo``
    and ``hi`` included: a uniform spacing of at most ``fine`` over ``focus = (a, b)`` (clipped to
    ``[lo, hi]``), spacings growing by ``growth`` per cell away from it up to ``coarse``."""
    if not hi > lo:
        raise MeshError(f"a graded axis needs hi > lo, got [{lo}, {hi}]")
    if not 0 < fine <= coarse or growth < 1:
        raise MeshError(f"a graded axis needs 0 < fine <= coarse and growth >= 1, got fine {fine}, coarse {coarse}, "
                        f"growth {growth}")
    a, b = np.clip(sorted(map(float, focus)), lo, hi)
    if b - a < fine:  # a focus thinner than a cell: one cell about its middle, inside [lo, hi]
        m = float(np.clip(0.5 * (a + b), lo + 0.5 * min(fine, hi - lo), hi - 0.5 * min(fine, hi - lo)))
        a, b = m - 0.5 * min(fine, hi - lo), m + 0.5 * min(fine, hi - lo)
    # a focus within half a fine cell of an end reaches it: no sliver cell between (a layer so
    # thin that surface points could not be located on it)
    a, b = (lo if a - lo < 0.5 * fine else a), (hi if hi - b < 0.5 * fine else b)
    inner = np.linspace(a, b, max(1, int(np.ceil((b - a) / fine - 1e-9))) + 1)
    left = a - np.cumsum(_outward(a - lo, fine, coarse, growth))
    right = b + np.cumsum(_outward(hi - b, fine, coarse, growth))
    ticks = np.r_[left[::-1], inner, right]
    ticks[0], ticks[-1] = lo, hi  # round-off of the sums
    return ticks


def graded_box(ticks: tuple, element: str = "tet10") -> Mesh:
    """A box meshed on the node coordinates ``ticks = (xs, ys, zs)`` (each increasing, length
    unit): :func:`jaxfem.mesh.box`'s bricks (``hex8``, or six ``tet4``/``tet10`` each) with brick
    ``(i, j, k)`` spanning ``[xs[i], xs[i+1]] x [ys[j], ys[j+1]] x [zs[k], zs[k+1]]``."""
    ticks = [np.asarray(t, float) for t in ticks]
    if len(ticks) != 3 or any(t.ndim != 1 or len(t) < 2 or not (np.diff(t) > 0).all() for t in ticks):
        raise MeshError("graded_box needs three increasing arrays of at least two node coordinates each")
    n = [len(t) - 1 for t in ticks]
    unit = box(0.0, 0.0, 0.0, *map(float, n), *n, element=element)
    # corner nodes sit at integers, mid-edge nodes half-way: piecewise-linear maps keep both
    nodes = np.stack([np.interp(unit.nodes[:, d], np.arange(n[d] + 1), ticks[d]) for d in range(3)], -1)
    return Mesh(nodes, unit.cells, unit.element, unit.regions, dict(unit.region_names))
