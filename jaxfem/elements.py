"""Reference elements: shape functions, their derivatives and quadrature rules.

An :class:`Element` is pure data evaluated once with numpy: the values and reference gradients of
its shape functions at its quadrature points. Everything that depends on the (differentiable)
nodal coordinates is computed later in JAX, so geometry stays a parameter like any other.

Available: ``tri3`` (linear triangle), ``tri6`` (quadratic triangle, the locking-free choice for
nearly incompressible plane problems), ``quad4`` (bilinear), ``tet4`` (linear tetrahedron),
``tet10`` (quadratic tetrahedron, locking-free in 3D) and ``hex8`` (trilinear).

In 3D, tet4 and hex8 lock when nearly incompressible while tet10 converges at about O(h^2) (a
Cook's membrane at nu = 0.499: tests/test_verify_locking3d.py), so a
:class:`~jaxfem.problem.Problem` refuses nu >= 0.45 with tet4 or hex8 in 3D.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import jax
import jax.numpy as jnp
import numpy as np

from .exceptions import MeshError


@dataclass(frozen=True)
class Element:
    """A reference finite element.

    Attributes:
        name: short name (``"tri3"``...).
        dim: spatial dimension of the reference cell.
        n_nodes: nodes per cell.
        points: quadrature points, shape ``(n_qp, dim)``.
        weights: quadrature weights, shape ``(n_qp,)``.
        N: shape-function values at the points, ``(n_qp, n_nodes)``.
        dN: reference gradients at the points, ``(n_qp, n_nodes, dim)``.
        shape: callable ``xi (..., dim) -> N (..., n_nodes)`` for interpolation anywhere.
        shape_grad: callable ``xi (dim,) -> dN (n_nodes, dim)``.
        facets: local node indices of each facet (edge in 2D, face in 3D), ``(n_facets, k)``.
        facet: the name of the facet element (``"line2"``...), or ``None`` for line elements.
        corners: number of vertex nodes (the first ``corners`` nodes are the vertices).
        meshio: the meshio cell-type name.
    """

    name: str
    dim: int
    n_nodes: int
    points: np.ndarray
    weights: np.ndarray
    shape: Callable = field(repr=False)
    shape_grad: Callable = field(repr=False)
    facets: np.ndarray = field(repr=False)
    facet: str | None
    corners: int
    meshio: str

    @property
    def N(self) -> np.ndarray:
        return np.stack([self.shape(p) for p in self.points])

    @property
    def dN(self) -> np.ndarray:
        return np.stack([self.shape_grad(p) for p in self.points])

    @property
    def n_qp(self) -> int:
        return len(self.weights)


def _num_grad(shape: Callable, dim: int) -> Callable:
    """Exact gradient of a polynomial shape function by complex-step differentiation
    (``xi (..., dim) -> (..., n_nodes, dim)``)."""

    def grad(xi):
        xi = np.asarray(xi, dtype=float)
        out = []
        for k in range(dim):
            z = xi.astype(complex)
            z[..., k] += 1e-30j
            out.append(np.imag(shape(z)) / 1e-30)
        return np.stack(out, axis=-1)

    return grad


# ---------------------------------------------------------------- shape functions (xi, eta, zeta)
def _stack(parts, axis):
    """``np.stack``, or ``jnp.stack`` for JAX arrays: the shape functions below then serve both the
    numpy reference data and differentiable interpolation inside JAX (e.g. ``Probe.moved``)."""
    if any(isinstance(q, jax.Array) for q in parts):
        return jnp.stack(parts, axis)
    return np.stack(parts, axis)


def _line2(x):
    s = x[..., 0]
    return _stack([(1 - s) / 2, (1 + s) / 2], -1)


def _line3(x):
    s = x[..., 0]
    return _stack([s * (s - 1) / 2, s * (s + 1) / 2, 1 - s * s], -1)


def _tri3(x):
    r, s = x[..., 0], x[..., 1]
    return _stack([1 - r - s, r, s], -1)


def _tri6(x):
    r, s = x[..., 0], x[..., 1]
    t = 1 - r - s
    return _stack([t * (2 * t - 1), r * (2 * r - 1), s * (2 * s - 1), 4 * r * t, 4 * r * s, 4 * s * t], -1)


def _quad4(x):
    r, s = x[..., 0], x[..., 1]
    return _stack([(1 - r) * (1 - s), (1 + r) * (1 - s), (1 + r) * (1 + s), (1 - r) * (1 + s)], -1) / 4


def _tet4(x):
    r, s, t = x[..., 0], x[..., 1], x[..., 2]
    return _stack([1 - r - s - t, r, s, t], -1)


def _tet10(x):
    r, s, t = x[..., 0], x[..., 1], x[..., 2]
    u = 1 - r - s - t
    # vtk / meshio ordering: vertices 0-3, then edges 01, 12, 20, 03, 13, 23
    return _stack([u * (2 * u - 1), r * (2 * r - 1), s * (2 * s - 1), t * (2 * t - 1),
                     4 * u * r, 4 * r * s, 4 * s * u, 4 * u * t, 4 * r * t, 4 * s * t], -1)


def _hex8(x):
    r, s, t = x[..., 0], x[..., 1], x[..., 2]
    sg = np.array([[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
                   [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], dtype=float)
    return _stack([(1 + a * r) * (1 + b * s) * (1 + c * t) / 8 for a, b, c in sg], -1)


# ---------------------------------------------------------------- quadrature rules
def _gauss_line(n):
    p, w = np.polynomial.legendre.leggauss(n)
    return p[:, None], w


def _gauss_tensor(n, dim):
    p, w = np.polynomial.legendre.leggauss(n)
    grids = np.meshgrid(*([p] * dim), indexing="ij")
    wg = np.meshgrid(*([w] * dim), indexing="ij")
    return np.stack([g.ravel() for g in grids], -1), np.prod([g.ravel() for g in wg], axis=0)


_TRI1 = (np.array([[1 / 3, 1 / 3]]), np.array([0.5]))
_TRI3 = (np.array([[1 / 6, 1 / 6], [2 / 3, 1 / 6], [1 / 6, 2 / 3]]), np.full(3, 1 / 6))
_TET1 = (np.array([[0.25, 0.25, 0.25]]), np.array([1 / 6]))
_a, _b = 0.5854101966249685, 0.1381966011250105
_TET4 = (np.array([[_b, _b, _b], [_a, _b, _b], [_b, _a, _b], [_b, _b, _a]]), np.full(4, 1 / 24))


def _make(name, dim, n, shape, rule, facets, facet, corners, meshio):
    return Element(name=name, dim=dim, n_nodes=n, points=np.asarray(rule[0], float),
                   weights=np.asarray(rule[1], float), shape=shape, shape_grad=_num_grad(shape, dim),
                   facets=np.asarray(facets, dtype=np.int64), facet=facet, corners=corners,
                   meshio=meshio)


ELEMENTS: dict[str, Element] = {
    "line2": _make("line2", 1, 2, _line2, _gauss_line(2), [[0], [1]], None, 2, "line"),
    "line3": _make("line3", 1, 3, _line3, _gauss_line(3), [[0], [1]], None, 2, "line3"),
    "tri3": _make("tri3", 2, 3, _tri3, _TRI1, [[0, 1], [1, 2], [2, 0]], "line2", 3, "triangle"),
    "tri6": _make("tri6", 2, 6, _tri6, _TRI3, [[0, 1, 3], [1, 2, 4], [2, 0, 5]], "line3", 3,
                  "triangle6"),
    "quad4": _make("quad4", 2, 4, _quad4, _gauss_tensor(2, 2), [[0, 1], [1, 2], [2, 3], [3, 0]],
                   "line2", 4, "quad"),
    "tet4": _make("tet4", 3, 4, _tet4, _TET1, [[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]], "tri3", 4,
                  "tetra"),
    "tet10": _make("tet10", 3, 10, _tet10, _TET4,
                   [[0, 2, 1, 6, 5, 4], [0, 1, 3, 4, 8, 7], [1, 2, 3, 5, 9, 8], [0, 3, 2, 7, 9, 6]],
                   "tri6", 4, "tetra10"),
    "hex8": _make("hex8", 3, 8, _hex8, _gauss_tensor(2, 3),
                  [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]],
                  "quad4", 8, "hexahedron"),
}

#: meshio cell-type name -> our element name
FROM_MESHIO = {e.meshio: e.name for e in ELEMENTS.values()}


def get_element(name: str) -> Element:
    """The reference element called ``name``; a clear error lists the known ones otherwise."""
    try:
        return ELEMENTS[name]
    except KeyError:
        raise MeshError(f"unknown element {name!r}; known: {', '.join(sorted(ELEMENTS))}") from None
