"""Shape geometry: a hole's or an inclusion's centre, axes and orientation as unknowns of a fit,
through a smooth morph of the mesh (the parametrisation :class:`ShapeGeometry`; the shapes built
by :func:`make_shape`). Split from :mod:`refine.model.parametrize`, which re-exports both."""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

import jaxfem as jf

from refine.exceptions import ParametrizationError


def _inverse_2x2(M, xp):
    """Inverses of ``M (n, 2, 2)`` in closed form (no LAPACK kernel in the compiled
    parametrisation: see :func:`jaxfem.probe.solve_small`)."""
    adj = xp.stack([xp.stack([M[:, 1, 1], -M[:, 0, 1]], -1), xp.stack([-M[:, 1, 0], M[:, 0, 0]], -1)], -2)
    return adj / (M[:, 0, 0] * M[:, 1, 1] - M[:, 0, 1] * M[:, 1, 0])[:, None, None]


# the morphed nodes of infeasibility's check on one program per shape of its arguments (a morph,
# jaxfem's Morph or refine.solid's ExtrudedMorph, is an equinox module: its arrays are arguments;
# run eagerly, each operation compiled a program per shape)
_affine_nodes = jax.jit(lambda morph, centres, maps: morph.affine(centres, maps))
_morphed_nodes = jax.jit(lambda morph, params: morph(params))


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
      fixed at a wrong start, a fit makes up for it with a larger, rounder ellipse. A shape whose
      entry in ``kinds`` is ``"rectangle"`` has instead the changes of its two half sides and of
      its angle (the last times ``scale / sqrt(a0 b0)`` radians, so that one unit turns its corners
      about one ``scale``): a symmetric map would shear a rectangle into a parallelogram.

    The mesh is never remeshed inside an optimisation. :meth:`infeasibility` turns a step down before
    any solve when a semi-axis would fall below ``min_axis`` (length units; a region thinner than
    the tracked points resolve is not identifiable, and its morph squashes cells), with ``mesh``
    when the morph would squash a cell below ``min_quality`` of its area, and with ``outside``
    when a shape (a hole) would cover a tracked point: material was seen there. Without these checks such steps cost a failed nonlinear solve
    each, and a hole fit could end with tracked points inside the hole.
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
            X = np.asarray(_affine_nodes(self.morph, c, maps))
        else:
            p = self._axis_aligned(z, np)
            if p[:, 2:4].min() <= max(self.min_axis, 1e-3 * self.scale):
                return f"a semi-axis would fall to {p[:, 2:4].min():.3g}"
            X = np.asarray(_morphed_nodes(self.morph, p))
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
