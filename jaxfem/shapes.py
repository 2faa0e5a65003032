"""Elliptic, rectangular and polygonal shapes (holes, inclusions, outlines) and a differentiable
morph of their curves in a mesh, for geometry fitting.

The shapes are meshed by :func:`jaxfem.mesher.plate` / :func:`jaxfem.mesher.domain` (element
edges on every curve). :func:`morph` prepares a JAX-differentiable map from new shape parameters
``(cx, cy, a, b, angle)`` to node coordinates; :func:`check_morph` says whether a morphed mesh is
valid and, if not, by how much to reduce the change. :func:`curve_nodes` finds the nodes on a
shape's curve in any 2D mesh.
"""

from __future__ import annotations

from dataclasses import dataclass

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from matplotlib.path import Path
from scipy.spatial import cKDTree

from . import _config  # noqa: F401  (float64)
from .exceptions import InvertedElementError, MeshError
from .mesh import Mesh


def _frame(p, xp=np):
    """Centre ``(..., 2)`` and ``A = R(angle) diag(a, b)`` ``(..., 2, 2)`` of parameters ``(..., 5)``
    (``xp`` is numpy, or jax.numpy for the differentiable morph)."""
    c, s = xp.cos(p[..., 4]), xp.sin(p[..., 4])
    rot = xp.stack([xp.stack([c, -s], -1), xp.stack([s, c], -1)], -2)
    return p[..., :2], rot * p[..., None, 2:4]


# ====================================================================== shapes
class _Affine:
    """A shape ``x = c + A xi`` with ``xi`` in the unit ball of the ``_ord`` norm (the unit disc
    for an ellipse, ``[-1, 1]^2`` for a rectangle); its morph moves ``c`` and ``A``."""

    _ord = 2.0
    _max_size = np.inf

    def to_unit(self, x: np.ndarray) -> np.ndarray:
        """Unit-shape coordinates ``xi`` ``(n, 2)`` of points ``x`` ``(n, 2)``."""
        c, A = _frame(self.params)
        return np.linalg.solve(A, (np.asarray(x, float) - c).T).T

    def _from_unit(self, xi):
        c, A = _frame(self.params)
        return c + xi @ A.T

    def contains(self, x: np.ndarray) -> np.ndarray:
        """Whether points ``(n, 2)`` are strictly inside, ``(n,)`` bool."""
        return np.linalg.norm(self.to_unit(x), self._ord, axis=1) < 1

    def to_curve(self, x: np.ndarray) -> np.ndarray:
        """Points ``(n, 2)`` moved radially (in unit coordinates) onto the boundary curve."""
        xi = self.to_unit(x)
        return self._from_unit(xi / np.maximum(np.linalg.norm(xi, self._ord, axis=1), 1e-300)[:, None])


@dataclass(frozen=True)
class Ellipse(_Affine):
    """Ellipse with centre ``(cx, cy)`` and semi-axes ``rx``, ``ry`` (length units), its ``rx`` axis
    turned ``angle`` radians counter-clockwise from x."""

    cx: float
    cy: float
    rx: float
    ry: float
    angle: float = 0.0

    def __post_init__(self):
        if not (self.rx > 0 and self.ry > 0):
            raise MeshError(f"an ellipse needs positive semi-axes, got rx={self.rx}, ry={self.ry}")

    @property
    def params(self) -> np.ndarray:
        """``(cx, cy, rx, ry, angle)``, the morph parameters."""
        return np.array([self.cx, self.cy, self.rx, self.ry, self.angle], float)

    @property
    def area(self) -> float:
        return float(np.pi * self.rx * self.ry)

    @property
    def min_radius_of_curvature(self) -> float:
        """The smallest radius of curvature, ``b^2 / a`` at the ends of the major axis (length units)."""
        a, b = max(self.rx, self.ry), min(self.rx, self.ry)
        return float(b * b / a)

    def _pieces(self, h):
        """One dense closed polyline ``(k, 2)`` and its radius of curvature ``(k,)``."""
        a, b = self.rx, self.ry
        perimeter = np.pi * (3 * (a + b) - np.sqrt((3 * a + b) * (a + 3 * b)))
        n = np.clip(max(64 * max(a, b) / min(a, b), 8 * perimeter / h), 2048, 2**17)  # resolve sharp ends
        t = np.linspace(0, 2 * np.pi, int(n) + 1)
        speed = np.hypot(a * np.sin(t), b * np.cos(t))
        return [(self._from_unit(np.stack([np.cos(t), np.sin(t)], -1)), speed**3 / (a * b))]


@dataclass(frozen=True)
class Rect(_Affine):
    """Rectangle ``[x0, x1] x [y0, y1]`` (length units), turned ``angle`` radians counter-clockwise
    about its centre."""

    x0: float
    y0: float
    x1: float
    y1: float
    angle: float = 0.0
    _ord = np.inf

    def __post_init__(self):
        if not (self.x1 > self.x0 and self.y1 > self.y0):
            raise MeshError(f"a rectangle needs x1 > x0 and y1 > y0, got {self}")

    @property
    def params(self) -> np.ndarray:
        """``(cx, cy, half width, half height, angle)``, the morph parameters."""
        return np.array([(self.x0 + self.x1) / 2, (self.y0 + self.y1) / 2, (self.x1 - self.x0) / 2,
                         (self.y1 - self.y0) / 2, self.angle], float)

    @property
    def area(self) -> float:
        return float((self.x1 - self.x0) * (self.y1 - self.y0))

    @property
    def _max_size(self):  # at least one element across a thin rectangle
        return min(self.x1 - self.x0, self.y1 - self.y0)

    @property
    def corners(self) -> np.ndarray:
        """The four corners ``(4, 2)``, counter-clockwise from ``(x0, y0)`` turned."""
        return self._from_unit(np.array([[-1.0, -1], [1, -1], [1, 1], [-1, 1]]))

    def _pieces(self, h):
        return _polygon_pieces(self.corners, h)


@dataclass(frozen=True, eq=False)
class Polygon:
    """Simple polygon with vertices ``(m, 2)`` (length units); an outline or a hole, not morphable."""

    vertices: np.ndarray
    _max_size = np.inf

    def __post_init__(self):
        v = np.asarray(self.vertices, float)
        if v.ndim != 2 or v.shape[1] != 2 or len(v) < 3:
            raise MeshError(f"a polygon needs vertices of shape (m >= 3, 2), got {v.shape}")
        object.__setattr__(self, "vertices", v)

    @property
    def area(self) -> float:
        x, y = self.vertices.T
        return float(abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))) / 2)

    def contains(self, x):
        return Path(self.vertices).contains_points(x)

    def to_curve(self, x):
        """Closest points ``(n, 2)`` on the sides."""
        a, b = self.vertices, np.roll(self.vertices, -1, axis=0)
        s = np.clip(np.einsum("nmi,mi->nm", x[:, None] - a, b - a) / ((b - a) ** 2).sum(1), 0, 1)
        p = a + s[..., None] * (b - a)  # (n, m, 2)
        return p[np.arange(len(x)), np.linalg.norm(p - x[:, None], axis=2).argmin(1)]

    def _pieces(self, h):
        return _polygon_pieces(self.vertices, h)


def _polygon_pieces(v, h):
    """Each side as a dense polyline with an infinite radius of curvature."""
    out = []
    for a, b in zip(v, np.roll(v, -1, axis=0)):
        s = np.linspace(0, 1, int(np.clip(8 * np.linalg.norm(b - a) / h, 16, 20000)) + 1)[:, None]
        out.append((a + s * (b - a), np.full(len(s), np.inf)))
    return out


def curve_nodes(mesh: Mesh, shape, tol: float | None = None) -> np.ndarray:
    """Indices of the nodes on the boundary curve of ``shape``, ordered by angle about their mean
    (counter-clockwise along an ellipse or rectangle).

    Works for any 2D mesh, one from :func:`plate` or one read from a file. ``tol`` is the largest
    distance from the curve (length units), by default ``1e-8`` times the mesh extent.
    """
    tol = 1e-8 * float(np.ptp(mesh.nodes, 0).max()) if tol is None else tol
    on = np.flatnonzero(np.linalg.norm(shape.to_curve(mesh.nodes) - mesh.nodes, axis=1) <= tol)
    if not on.size:
        return on
    rel = mesh.nodes[on] - mesh.nodes[on].mean(0)
    return on[np.argsort(np.arctan2(rel[:, 1], rel[:, 0]))]


def min_angles(mesh: Mesh) -> np.ndarray:
    """Smallest corner angle of every 2D cell in degrees, ``(n_cells,)``."""
    v = mesh.nodes[mesh.cells[:, : mesh.el.corners]]
    a, b = np.roll(v, 1, axis=1) - v, np.roll(v, -1, axis=1) - v
    cos = (a * b).sum(-1) / (np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1))
    return np.degrees(np.arccos(np.clip(cos, -1, 1))).min(1)


# ====================================================================== morph
class Morph(eqx.Module):
    """Smooth map from shape parameters to node coordinates, made by :func:`morph`.

    ``morph(params)``, with ``params`` ``(n_shapes, 5)`` = ``(cx, cy, a, b, angle)`` per shape
    (``a, b`` the semi-axes of an ellipse or the half sides of a rectangle, angle in radians),
    returns the nodes ``(n_nodes, 2)``; ``morph(morph.params0)`` returns the reference nodes.
    """

    nodes0: np.ndarray  # (n_nodes, 2)
    params0: np.ndarray  # (n_shapes, 5)
    weights: np.ndarray  # (n_shapes, n_nodes): 1 on and inside a shape, 0 on other boundaries

    def __call__(self, params):
        return morph_nodes(self.nodes0, params, self.params0, self.weights)

    def affine(self, centres, maps):
        """Nodes after moving each shape by an affine map of its own: the points ``x`` of shape
        ``s`` go to ``centres[s] + maps[s] @ (x - c0[s])`` (``c0`` its reference centre), others
        by that map blended with the weights. ``centres`` ``(n_shapes, 2)``, ``maps``
        ``(n_shapes, 2, 2)``; a map that is not a rotation times a scaling along the shape's axes
        turns an ellipse into another ellipse (any orientation) but a rectangle into a
        parallelogram. Differentiable in both."""
        c0 = jnp.asarray(self.params0)[:, :2]
        return _blend(jnp.asarray(self.nodes0), c0, jnp.asarray(centres), jnp.asarray(maps), jnp.asarray(self.weights))


def morph(mesh: Mesh, shapes, band: float | None = None) -> Morph:
    """Prepare a differentiable morph of ``mesh`` that moves the curves of ``shapes``.

    The nodes on (and inside) a shape move by the affine map that takes the reference shape onto
    the new one, so they stay exactly on the new ellipse or rectangle. Every other node moves by
    that map times ``w = 1 - smoothstep(d / (d + d_other))``, with ``d`` its distance to the shape
    and ``d_other`` to the nearest node of another boundary or region interface, which therefore
    stay put. With ``band`` (length units) ``w`` is also 0 farther than ``band`` from the shape.

    Args:
        mesh: a 2D mesh whose boundary or region interfaces contain the curves of ``shapes``.
        shapes: :class:`Ellipse` or :class:`Rect` instances, e.g. those given to :func:`plate`.
        band: optional reach of the morph (length units).
    """
    nodes = mesh.nodes
    features = np.union1d(mesh.boundary_nodes(), _interface_nodes(mesh))
    weights = []
    for shape in shapes:
        if not isinstance(shape, _Affine):
            raise MeshError(f"only Ellipse and Rect shapes can be morphed, not {type(shape).__name__}")
        on = curve_nodes(mesh, shape)
        if len(on) < 3:
            raise MeshError(f"no curve of the mesh follows {shape}; pass the shapes used to build it")
        other = np.setdiff1d(features, on)
        dense = np.concatenate([p for p, _ in shape._pieces(np.ptp(nodes, 0).max() / 1000)])
        d = cKDTree(dense).query(nodes)[0]
        d_other = cKDTree(nodes[other]).query(nodes)[0] if len(other) else np.full(len(nodes), np.inf)
        t = np.clip(d / np.maximum(d + d_other, 1e-300), 0, 1)
        if band is not None:
            t = np.maximum(t, np.clip(d / band, 0, 1))
        w = 1 - t * t * (3 - 2 * t)
        w[on], w[shape.contains(nodes)], w[other] = 1.0, 1.0, 0.0
        weights.append(w)
    return Morph(nodes, np.stack([s.params for s in shapes]), np.stack(weights))


def _interface_nodes(mesh: Mesh) -> np.ndarray:
    """Nodes shared by cells of different regions."""
    r = np.repeat(mesh.regions, mesh.cells.shape[1])
    lo, hi = np.full(mesh.n_nodes, r.max(initial=0)), np.full(mesh.n_nodes, r.min(initial=0))
    np.minimum.at(lo, mesh.cells.ravel(), r)
    np.maximum.at(hi, mesh.cells.ravel(), r)
    return np.flatnonzero(lo != hi)


@jax.jit
def morph_nodes(nodes0, params, params0, weights):
    """Morphed nodes ``(n_nodes, 2)``: pure JAX, differentiable in ``params``.

    Args:
        nodes0: reference nodes ``(n_nodes, 2)``.
        params: new shape parameters ``(n_shapes, 5)`` = ``(cx, cy, a, b, angle)``.
        params0: reference shape parameters ``(n_shapes, 5)``.
        weights: blend weights ``(n_shapes, n_nodes)`` (see :func:`morph`).
    """
    c0, A0 = _frame(jnp.asarray(params0), jnp)
    c1, A1 = _frame(jnp.asarray(params), jnp)
    (a, b), (c, d) = A0[:, 0].T, A0[:, 1].T
    inv = jnp.stack([jnp.stack([d, -b], -1), jnp.stack([-c, a], -1)], -2) / (a * d - b * c)[:, None, None]
    M = A1 @ inv  # (s, 2, 2): each reference shape onto the new one
    return _blend(jnp.asarray(nodes0), c0, c1, M, jnp.asarray(weights))


def _blend(x, c0, c1, M, weights):
    """``x + sum_s w_s (c1_s + M_s (x - c0_s) - x)``: each shape's affine map, blended."""
    d = jnp.einsum("sij,snj->sni", M, x[None] - c0[:, None]) + c1[:, None] - x[None]
    return x + jnp.einsum("sn,sni->ni", weights, d)


def check_morph(mesh: Mesh, nodes) -> float:
    """Smallest ratio of morphed to reference Jacobian over all cells and quadrature points.

    Raises:
        InvertedElementError: a cell inverts; the message says what fraction of the change is valid.
    """
    nodes = np.asarray(nodes, float)
    ratio = mesh.jacobian_dets(nodes) / mesh.jacobian_dets()
    bad = np.flatnonzero((ratio <= 0).any(1))
    if bad.size:
        u, lo, hi = nodes - mesh.nodes, 0.0, 1.0
        for _ in range(30):  # largest s with nodes0 + s u valid; the morph is linear in (c, a, b)
            s = 0.5 * (lo + hi)
            lo, hi = (s, hi) if (mesh.jacobian_dets(mesh.nodes + s * u) > 0).all() else (lo, s)
        worst = ratio.min(1).argmin()
        raise InvertedElementError(
            f"the morph inverts {bad.size} of {mesh.n_cells} cells (worst: cell {worst} near x = "
            f"{mesh.centroids()[worst].round(3).tolist()}); only about {lo:.0%} of this change keeps "
            f"every cell valid: scale the change of centre and axes by at most {0.9 * lo:.2f}, or keep "
            "the shape farther from other boundaries")
    return float(ratio.min())
