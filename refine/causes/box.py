"""A box-shaped region of other stiffness in a solid (3D), the cause added as one file: centre,
half-sizes, orientation and log modulus ratio fitted by exact gradients as the ellipsoid's
(:mod:`refine.solid.inclusion`): each cell holds the smooth share ``sigmoid(-d / width)`` of the
box, ``d`` the signed distance to its surface, averaged over the cell's sample points, and the
Mori-Tanaka modulus of that share. A reshape: it starts from a fitted ellipsoid (the box of its
volume, the same orientation and ratio); it names ``"stiffer-region"`` or ``"softer-region"``.

Unknowns ``z (10,)``: the log ratio, the centre's change (3, units of ``scale``), the log of the
half-sizes' factors (3) and a rotation vector (3, radians) applied after the start's rotation.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import jax
import jax.numpy as jnp
import numpy as np

from refine.causes.registry import Cause, register
from refine.diagnosis.fitted import fit
from refine.model.measured import MeasuredModel
from refine.model.objective import Compiled
from refine.solid.inclusion import MAX_LOG_RATIO, cell_size, cell_sizes, mori_tanaka, sample_points

EQUAL_VOLUME = float(np.cbrt(np.pi / 6.0))
"""A box's half-size per semi-axis of the ellipsoid of its volume."""


def rotation(w, xp=jnp):
    """The rotation ``(3, 3)`` by the rotation vector ``w (3,)`` (Rodrigues; smooth through 0)."""
    w = xp.asarray(w)
    t = xp.sqrt(xp.sum(w * w) + 1e-12)
    K = xp.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
    return xp.eye(3) + xp.sin(t) / t * K + (1.0 - xp.cos(t)) / t**2 * (K @ K)


@dataclass(frozen=True)
class BoxShape:
    """A fitted box: ``centre (3,)``, half-sizes ``axes (3,)`` (larger first) along the columns of
    ``rotation (3, 3)``, modulus ``ratio`` times the background's."""

    centre: tuple
    axes: tuple
    rotation: tuple
    ratio: float

    kind = "box"

    @property
    def volume(self) -> float:
        return float(8.0 * np.prod(self.axes))

    @property
    def cause(self) -> str:
        return "stiffer-region" if self.ratio > 1 else "softer-region"

    def describe(self) -> str:
        c, a = np.round(self.centre, 2).tolist(), np.round(self.axes, 2).tolist()
        return f"box at {c}, half-sizes {a}, volume {self.volume:.1f}, x{self.ratio:.3g}"

    def moved(self, other) -> float:
        return float(np.abs(np.r_[np.subtract(self.centre, other.centre), np.subtract(self.axes, other.axes)]).max())


@dataclass(frozen=True, eq=False)
class BoxModulus:
    """The parametrisation of one box (see the module) on ``mesh``: started at ``centre0``,
    half-sizes ``half0`` along the columns of ``R0``; lengths in units of ``scale``; the
    indicator's ``width`` (a number or ``(n_cells, 1)``); a half-size kept above ``min_axis``."""

    mesh: object
    centre0: np.ndarray
    R0: np.ndarray
    half0: np.ndarray
    scale: float
    width: object
    min_axis: float
    log_ratio0: float
    nu: float
    samples: np.ndarray = field(default=None)

    size = 10

    def __post_init__(self):
        if self.samples is None:
            object.__setattr__(self, "samples", sample_points(self.mesh))

    @property
    def z0(self):
        return jnp.zeros(self.size).at[0].set(self.log_ratio0)

    def geometry(self, z, xp=jnp):
        """The log ratio, centre ``(3,)``, half-sizes ``(3,)`` and rotation ``(3, 3)`` at ``z``."""
        z = xp.asarray(z)
        return (z[0], xp.asarray(self.centre0) + self.scale * z[1:4], xp.asarray(self.half0) * xp.exp(z[4:7]),
                xp.asarray(self.R0) @ rotation(z[7:10], xp))

    def fraction(self, z):
        """``(n_cells,)``: the smooth share of each cell inside the box at ``z``."""
        _, c, h, R = self.geometry(z)
        q = jnp.abs((jnp.asarray(self.samples) - c) @ R) - h
        out = jnp.sqrt(jnp.sum(jnp.maximum(q, 0.0) ** 2, -1) + 1e-12) - 1e-6
        d = out + jnp.minimum(jnp.max(q, -1), 0.0)
        return jnp.mean(jax.nn.sigmoid(-d / self.width), axis=-1)

    def apply(self, theta, z):
        return {**theta, "E": theta["E"] * mori_tanaka(self.fraction(z), jnp.asarray(z)[0], self.nu)}

    def regularization(self, z):
        return 0.0

    def shape(self, z) -> BoxShape:
        lr, c, h, R = self.geometry(np.asarray(z, float), np)
        order = np.argsort(h)[::-1]
        return BoxShape(tuple(map(float, c)), tuple(map(float, h[order])), tuple(map(tuple, R[:, order])),
                        float(np.exp(lr)))

    def infeasibility(self, z) -> str | None:
        z = np.asarray(z, float)
        if not np.isfinite(z).all():
            return "the step is not a finite number"
        _, c, h, _ = self.geometry(z, np)
        if h.min() <= self.min_axis:
            return f"a half-size would fall to {h.min():.3g}"
        lo, hi = self.mesh.bounds()
        if (c < lo).any() or (c > hi).any():
            return f"the centre would leave the body, at {np.round(c, 2).tolist()}"
        if abs(z[0]) > MAX_LOG_RATIO:
            return f"the ratio would reach {np.exp(z[0]):.3g}"
        return None

    def values(self, z) -> dict:
        s = self.shape(z)
        return {"box": {"centre": list(s.centre), "half_sizes": list(s.axes), "volume": s.volume,
                        "relative_elasticity": s.ratio}}


@dataclass(frozen=True, eq=False)
class BoxInclusion:
    """The hypothesis of one box in ``model``, started at ``centre``, half-sizes ``axes`` along
    the columns of ``rotation`` and ``ratio`` (nothing to remesh)."""

    model: MeasuredModel
    centre: tuple
    axes: tuple
    rotation: tuple
    ratio: float
    remeshable = False

    @property
    def law(self) -> str:
        return self.model.experiment.law

    def build(self):
        mesh = self.model.mesh
        R = np.asarray(self.rotation, float)
        sizes = cell_sizes(mesh)
        local = (mesh.centroids() - np.asarray(self.centre, float)) @ R
        within = (np.abs(local) <= np.asarray(self.axes, float)).all(axis=1)
        h = float(np.median(sizes[within])) if within.any() else cell_size(mesh)
        param = BoxModulus(mesh, np.asarray(self.centre, float), R, np.asarray(self.axes, float), 0.5 * h,
                           0.1 * sizes[:, None], 0.25 * h, float(np.log(self.ratio)), float(self.model.experiment.nu))
        return Compiled(self.model, param), np.asarray(param.z0)

    def shapes_at(self, compiled, z):
        return (compiled.param.shape(z),)

    def cause_of(self, shapes) -> str:
        return shapes[0].cause if shapes else "none"

    def at(self, shapes, element):
        return None

    def on(self, model, shapes) -> BoxInclusion:
        s = shapes[0]
        return BoxInclusion(model, tuple(s.centre), tuple(s.axes), tuple(map(tuple, np.asarray(s.rotation))),
                            float(s.ratio))


def jobs(search, start) -> dict:
    """One fit from a fitted ellipsoid ``start`` (a Fitted; nothing from another shape): the box
    of its volume, orientation and ratio."""
    shapes = getattr(start, "shapes", ())
    if len(shapes) != 1 or shapes[0].kind != "ellipsoid":
        return {}
    s = shapes[0]
    hyp = BoxInclusion(search.model, tuple(s.centre), tuple(EQUAL_VOLUME * np.asarray(s.axes)),
                       tuple(map(tuple, np.asarray(s.rotation))), float(s.ratio))
    return {"box": lambda: fit(hyp, search.fit, search.hold, search.sigma)}


CAUSE = register(Cause("box", {3}, "reshape", ("stiffer-region", "softer-region"), jobs,
                       doc="a box-shaped region of other stiffness", order=30))
