"""Parametrisations: how a short vector z of unknowns becomes the solver's parameters.

Moduli are always fitted in log space (a modulus stays positive and a factor of 2 up or down is
the same step). Each parametrisation has ``size``, ``z0``, ``apply(theta, z) -> theta``,
``regularization(z)`` and ``values(z) -> dict`` for reports; a new one is a new class.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import jax
import jax.numpy as jnp
import numpy as np

import jaxfem as jf

from refine.exceptions import ParametrizationError


@dataclass(frozen=True, eq=False)
class RegionModuli:
    """One modulus per region: E = E0 exp(z_k) on the cells of region k (applied as a factor
    exp(z_k) on the base parameters' moduli, which are E0 where the initial model is uniform).

    Args:
        masks: ``(n_regions, n_cells)`` membership (1 inside, 0 outside).
        E0: reference modulus (the initial background), stress units.
        names: one per region.
        background: also fit the background modulus (only identifiable with measured forces);
            it is then the first unknown, named ``"background"``.
    """

    masks: np.ndarray
    E0: float
    names: tuple = ()
    background: bool = False

    def __post_init__(self):
        m = np.atleast_2d(np.asarray(self.masks, float))
        object.__setattr__(self, "masks", m)
        if not self.names:
            object.__setattr__(self, "names", tuple(f"region{k + 1}" for k in range(len(m))))

    @property
    def size(self) -> int:
        return len(self.masks) + int(self.background)

    @property
    def z0(self):
        return jnp.zeros(self.size)

    def moduli(self, z):
        """Per-cell modulus ``(n_cells,)``."""
        z = jnp.asarray(z)
        bg = z[0] if self.background else 0.0
        zr = z[1:] if self.background else z
        logE = bg + jnp.asarray(self.masks).T @ zr
        return self.E0 * jnp.exp(logE)

    def apply(self, theta, z):
        # relative to the base moduli (E0 where the initial model is uniform; known regions keep theirs)
        return {**theta, "E": theta["E"] * (self.moduli(z) / self.E0)}

    def regularization(self, z):
        return 0.0

    def values(self, z) -> dict:
        z = np.asarray(z)
        bg = float(np.exp(z[0])) if self.background else 1.0
        zr = z[1:] if self.background else z
        out = {"background_modulus": self.E0 * bg} if self.background else {}
        for name, zk in zip(self.names, zr):
            out[f"{name}_relative_elasticity"] = float(np.exp(zk))  # relative to the background
            out[f"{name}_modulus"] = float(self.E0 * bg * np.exp(zk))
        return out


def infeasibility(param, z) -> str | None:
    """Why a parametrisation cannot take the value ``z`` without a solve (None: it can, or it has
    no such check)."""
    check = getattr(param, "infeasibility", None)
    return check(z) if check is not None else None


def cell_adjacency(mesh: jf.Mesh) -> np.ndarray:
    """Pairs of cells that share a facet, ``(n_pairs, 2)``."""
    f = mesh.facets()
    nf = mesh.el.facets.shape[0]
    owner = np.repeat(np.arange(mesh.n_cells), nf)
    key = np.sort(f[:, : jf.get_element(mesh.el.facet).corners], axis=1)
    order = np.lexsort(key.T[::-1])
    k, o = key[order], owner[order]
    same = np.all(k[1:] == k[:-1], axis=1)
    return np.stack([o[:-1][same], o[1:][same]], 1)


@dataclass(frozen=True, eq=False)
class ModulusField:
    """A modulus per cell, E = E0 exp(z) (applied as a factor exp(z) on the base moduli), with a
    smoothness penalty on neighbouring cells.

    Args:
        mesh: the inversion mesh.
        E0: reference modulus.
        weight: penalty weight (in units of the misfit, i.e. of squared noise-weighted residuals).
        kind: ``"tikhonov"`` (sum of squared jumps of log E between neighbours: smooth fields) or
            ``"tv"`` (total variation, sum of |jumps|, smoothed by ``eps``: sharp-edged regions).
    """

    mesh: jf.Mesh
    E0: float
    weight: float = 1.0
    kind: str = "tikhonov"
    eps: float = 1e-2
    pairs: np.ndarray = field(default=None)

    def __post_init__(self):
        if self.kind not in ("tikhonov", "tv"):
            raise ParametrizationError(f"the regulariser's kind must be 'tikhonov' or 'tv', not {self.kind!r}")
        if self.pairs is None:
            object.__setattr__(self, "pairs", cell_adjacency(self.mesh))

    @property
    def size(self) -> int:
        return self.mesh.n_cells

    @property
    def z0(self):
        return jnp.zeros(self.size)

    def moduli(self, z):
        return self.E0 * jnp.exp(jnp.asarray(z))

    def apply(self, theta, z):
        # relative to the base moduli (E0 where the initial model is uniform; known regions keep theirs)
        return {**theta, "E": theta["E"] * (self.moduli(z) / self.E0)}

    def regularization(self, z):
        d = jnp.asarray(z)[self.pairs[:, 0]] - jnp.asarray(z)[self.pairs[:, 1]]
        if self.kind == "tikhonov":
            return self.weight * jnp.sum(d * d)
        return self.weight * jnp.sum(jnp.sqrt(d * d + self.eps**2) - self.eps)

    def values(self, z) -> dict:
        z = np.asarray(z)
        return {"log_relative_modulus": z, "min_relative": float(np.exp(z.min())),
                "max_relative": float(np.exp(z.max()))}


@dataclass(frozen=True, eq=False)
class Combined:
    """Several parametrisations side by side (z is their concatenation)."""

    parts: tuple

    @property
    def size(self) -> int:
        return sum(p.size for p in self.parts)

    @property
    def z0(self):
        return jnp.concatenate([jnp.asarray(p.z0, float) for p in self.parts])

    def _split(self, z):
        out, i = [], 0
        for p in self.parts:
            out.append(z[i:i + p.size])
            i += p.size
        return out

    def apply(self, theta, z):
        for p, zp in zip(self.parts, self._split(jnp.asarray(z))):
            theta = p.apply(theta, zp)
        return theta

    def regularization(self, z):
        return sum(p.regularization(zp) for p, zp in zip(self.parts, self._split(jnp.asarray(z))))

    def infeasibility(self, z) -> str | None:
        """The first part's reason why ``z`` is not feasible (None: every part is)."""
        for p, zp in zip(self.parts, self._split(np.asarray(z, float))):
            why = infeasibility(p, zp)
            if why:
                return why
        return None

    def values(self, z) -> dict:
        out = {}
        for p, zp in zip(self.parts, self._split(np.asarray(z))):
            out.update(p.values(zp))
        return out


def _inverse_2x2(M, xp):
    """Inverses of ``M (n, 2, 2)`` in closed form (no LAPACK kernel in the compiled
    parametrisation: see :func:`jaxfem.probe.solve_small`)."""
    adj = xp.stack([xp.stack([M[:, 1, 1], -M[:, 0, 1]], -1), xp.stack([-M[:, 1, 0], M[:, 0, 0]], -1)], -2)
    return adj / (M[:, 0, 0] * M[:, 1, 1] - M[:, 0, 1] * M[:, 1, 0])[:, None, None]


def make_shape(kind: str, params):
    """A ``jaxfem.Ellipse`` (``kind="ellipse"``) or ``jaxfem.Rect`` (``"rectangle"``) from
    ``(cx, cy, a, b, angle)``: centre, semi-axes or half sides, angle (radians)."""
    cx, cy, a, b, ang = map(float, params)
    if kind == "ellipse":
        return jf.Ellipse(cx, cy, a, b, ang)
    if kind == "rectangle":
        return jf.Rect(cx - a, cy - b, cx + a, cy + b, ang)
    raise ParametrizationError(f"unknown shape kind {kind!r}; use 'ellipse' or 'rectangle'")


@dataclass(frozen=True, eq=False)
class ShapeGeometry:
    """Hole or inclusion geometry through a smooth mesh morph (``jaxfem.morph``).

    z holds, per shape, the change of its centre (2 unknowns) and of its size, in length units
    scaled by ``scale``:

    - ``rotate=False`` (any shape, rectangles included): the changes of the two axes ``a, b``
      along the shape's fixed orientation (4 unknowns per shape);
    - ``rotate=True`` (ellipses): the changes of the symmetric matrix
      ``M = R(angle) diag(a, b) R(angle)^T`` that maps the unit circle onto the ellipse, entries
      ``(M11, M22, M12)`` (5 unknowns per shape). Axes and orientation are then fitted together
      and smoothly, also through a circle where an angle alone is undefined. With the orientation
      fixed at a wrong start, a fit makes up for it with a larger, rounder ellipse (a hole's area
      came out 20 % too large on noise-free data). A shape whose entry in ``kinds`` is
      ``"rectangle"`` has instead the changes of its two half sides and of its angle (the last
      times ``scale / sqrt(a0 b0)`` radians, so that one unit turns its corners about one
      ``scale``): a symmetric map would shear a rectangle into a parallelogram.

    The mesh is never remeshed inside an optimisation. :meth:`infeasibility` turns a step down before
    any solve when a semi-axis would fall below ``min_axis`` (length units; a region thinner than
    the tracked points resolve is not identifiable, and its morph squashes cells), with ``mesh``
    when the morph would squash a cell below ``min_quality`` of its area, and with ``outside``
    when a shape (a hole) would cover a tracked point: material was seen there. Without these checks such steps cost a failed nonlinear solve
    each (a hole fit of a softer region spent 10-30 s on each of a dozen, 600 s in all, and
    ended with tracked points inside the hole).
    """

    morph: object
    params0: np.ndarray
    scale: float = 1.0
    names: tuple = ()
    rotate: bool = False
    mesh: object = None
    outside: np.ndarray | None = None
    min_quality: float = 0.2
    min_axis: float = 0.0
    kinds: tuple = ()

    @property
    def per_shape(self) -> int:
        return 5 if self.rotate else 4

    @property
    def size(self) -> int:
        return self.per_shape * len(self.params0)

    @property
    def z0(self):
        return jnp.zeros(self.size)

    def _axis_aligned(self, z, xp):
        """Without ``rotate``: the new ``(cx, cy, a, b, angle)`` per shape, angle kept."""
        dz = xp.reshape(xp.asarray(z), (-1, 4)) * self.scale
        return xp.asarray(self.params0, dtype=float) + xp.concatenate([dz, xp.zeros((dz.shape[0], 1))], 1)

    @property
    def _kinds(self) -> tuple:
        """Each shape's kind (``kinds``, by default all ellipses)."""
        kinds = tuple(self.kinds) or ("ellipse",) * len(self.params0)
        if len(kinds) != len(self.params0) or set(kinds) - {"ellipse", "rectangle"}:
            raise ParametrizationError(f"kinds must name 'ellipse' or 'rectangle' for each of {len(self.params0)} shapes, "
                             f"got {kinds}")
        return kinds

    def _is_rect(self) -> np.ndarray:
        return np.array([k == "rectangle" for k in self._kinds])

    def _affine(self, z, xp):
        """With ``rotate``: new centres ``(n, 2)``, the affine maps ``(n, 2, 2)`` that take each
        reference shape onto its new one, and the new ``(a, b, angle)`` per shape ``(n, 3)``
        (for an ellipse, ``a`` the axis closest in direction to the reference's ``a``)."""
        dz = xp.reshape(xp.asarray(z), (-1, 5)) * self.scale
        p = xp.asarray(self.params0, dtype=float)
        rect = self._is_rect()

        def rot(t):
            c, s = xp.cos(t), xp.sin(t)
            return xp.stack([xp.stack([c, -s], -1), xp.stack([s, c], -1)], -2)

        R0 = rot(p[:, 4])
        # ellipses: M = M0 + dM, symmetric
        M0 = R0 @ (p[:, 2:4, None] * xp.swapaxes(R0, -1, -2))
        dM = xp.stack([xp.stack([dz[:, 2], dz[:, 4]], -1), xp.stack([dz[:, 4], dz[:, 3]], -1)], -2)
        ell_map = (M0 + dM) @ _inverse_2x2(M0, xp)
        # rectangles: A = R(angle) diag(a, b), half sides and angle changed
        r0 = xp.sqrt(p[:, 2] * p[:, 3])
        a1, b1, t1 = p[:, 2] + dz[:, 2], p[:, 3] + dz[:, 3], p[:, 4] + dz[:, 4] / r0
        A0 = R0 * p[:, None, 2:4]
        A1 = rot(t1) * xp.stack([a1, b1], -1)[:, None, :]
        rect_map = A1 @ _inverse_2x2(A0, xp)
        maps = xp.where(xp.asarray(rect)[:, None, None], rect_map, ell_map)
        return p[:, :2] + dz[:, :2], maps, (M0 + dM, xp.stack([a1, b1, t1], -1))

    def shape_params(self, z) -> np.ndarray:
        """``(n_shapes, 5)`` = ``(cx, cy, a, b, angle)``; with ``rotate`` an ellipse's axis ``a`` is
        the one closest in direction to the starting shape's, and the angle stays within a
        quarter turn of the start's."""
        if not self.rotate:
            return self._axis_aligned(np.asarray(z, float), np)
        c, _, (M, rect_abt) = self._affine(np.asarray(z, float), np)
        p0 = np.asarray(self.params0, float)
        out = []
        for k, is_rect in enumerate(self._is_rect()):
            if is_rect:
                out.append([c[k, 0], c[k, 1], *rect_abt[k]])
                continue
            w, V = np.linalg.eigh(M[k])
            d0 = np.array([np.cos(p0[k, 4]), np.sin(p0[k, 4])])
            i = int(np.argmax(np.abs(V.T @ d0)))
            ang = float(np.arctan2(V[1, i], V[0, i]))
            ang += np.pi * np.round((p0[k, 4] - ang) / np.pi)
            out.append([c[k, 0], c[k, 1], w[i], w[1 - i], ang])
        return np.asarray(out)

    def shapes(self, z) -> list:
        """The shapes at ``z``: ``jaxfem.Ellipse`` or ``jaxfem.Rect`` instances."""
        return [make_shape(kind, p) for kind, p in zip(self._kinds, self.shape_params(z))]

    def apply(self, theta, z):
        if not self.rotate:
            return {**theta, "X": self.morph(self._axis_aligned(z, jnp))}
        c, maps, _ = self._affine(z, jnp)
        return {**theta, "X": self.morph.affine(c, maps)}

    def regularization(self, z):
        return 0.0

    def infeasibility(self, z) -> str | None:
        """Why the shapes at ``z`` cannot be solved or are not physical (None: they can)."""
        z = np.asarray(z, float)
        if self.rotate:
            c, maps, (M, rect_abt) = self._affine(z, np)
            rect = self._is_rect()
            axes = np.concatenate([np.linalg.eigvalsh(M[~rect]).ravel(), rect_abt[rect, :2].ravel()])
            if axes.min() <= max(self.min_axis, 1e-3 * self.scale):
                return f"a semi-axis would fall to {axes.min():.3g}"
            X = np.asarray(self.morph.affine(c, maps))
        else:
            p = self._axis_aligned(z, np)
            if p[:, 2:4].min() <= max(self.min_axis, 1e-3 * self.scale):
                return f"a semi-axis would fall to {p[:, 2:4].min():.3g}"
            X = np.asarray(self.morph(p))
        if self.mesh is not None:
            quality = (self.mesh.jacobian_dets(X) / self.mesh.jacobian_dets()).min()
            if quality < self.min_quality:
                return f"the morph would squash a cell to {quality:.2f} of its area"
        if self.outside is not None and len(self.outside):
            for shape in self.shapes(z):
                inside = shape.contains(self.outside)
                if inside.any():
                    return f"the shape would cover the tracked point at {self.outside[inside][0].round(2).tolist()}"
        return None

    def values(self, z) -> dict:
        p = self.shape_params(z)
        names = self.names or tuple(f"shape{k + 1}" for k in range(len(p)))
        kinds = self._kinds
        return {n: {"kind": kinds[k], "centre": p[k, :2].tolist(), "axes": p[k, 2:4].tolist(),
                    "angle": float(p[k, 4])} for k, n in enumerate(names)}


@dataclass(frozen=True, eq=False)
class UniformParameter:
    """One material parameter uniform over the body (e.g. ``nu`` or ``c01_fraction``), fitted
    through a smooth bounded map ``value = lo + (hi - lo) * sigmoid(z)`` started at ``start``."""

    key: str
    start: float
    lo: float
    hi: float

    @property
    def size(self) -> int:
        return 1

    @property
    def z0(self):
        s = (self.start - self.lo) / (self.hi - self.lo)
        return jnp.array([np.log(s / (1 - s))])

    def value(self, z):
        return self.lo + (self.hi - self.lo) * jax.nn.sigmoid(jnp.asarray(z)[0])

    def apply(self, theta, z):
        return {**theta, self.key: jnp.full_like(theta[self.key], self.value(z))}

    def regularization(self, z):
        return 0.0

    def values(self, z) -> dict:
        return {self.key: float(self.value(z))}
