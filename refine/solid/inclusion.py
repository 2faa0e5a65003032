"""The hypothesis of an ellipsoidal inclusion in a solid: a region of other stiffness whose centre,
semi-axes, orientation and log modulus ratio are fitted by exact gradients (Levenberg-Marquardt,
forward-mode tangents through the solver) on the model's own mesh, never remeshed.

The ellipsoid is ``{x : |M^-1 (x - c)| <= 1}`` with ``M`` symmetric positive definite (its
eigenvalues the semi-axes, its eigenvectors their directions), so axes and orientation change
together and smoothly, through a sphere too. A cell holds the share ``f`` of the inclusion: the
mean over 84 sample points of the cell of a smooth indicator ``sigmoid(-d / width)``, ``d`` the
signed distance to the surface to first order (its volume exact:
:meth:`EllipsoidModulus.fraction`), ``width`` a tenth of the cell size, so that the misfit is a
smooth function of the shape (a cell-centroid test, all or nothing, is not). Its modulus is the
Mori-Tanaka estimate of the background holding that share of the inclusion's material
(:func:`mori_tanaka`): ``E exp(log_ratio f)`` instead makes a partly covered cell far too stiff,
and a fit then runs to a small volume at the ratio's bound.

Seen from the surface alone, the inclusion's volume and ratio trade against each other: fits
place it well but can come out small and more extreme, some at the ratio's bound
(:data:`MAX_LOG_RATIO`; benchmarks/inclusion3d.py), with the strength the
surface fixes (:func:`refine.solid.inclusion_profile.strength`) close to the truth's; the report
gives the ratio's profile (:mod:`refine.solid.inclusion_profile`) for the intervals. Part of
the smallness is the coarse model's bias along that valley: the diagnosis refits the inclusion on
the block graded fine around it (:mod:`refine.solid.inclusion_mesh`).

Unknowns ``z (10,)``: the log ratio, the change of the centre (3) and of ``M``'s entries
``(M11, M22, M33, M12, M13, M23)``, all lengths in units of ``scale``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Float

from jaxfem.probe import solve_small

from refine.model.measured import MeasuredModel
from refine.model.objective import Compiled

MAX_LOG_RATIO = 5.0
"""The largest |log ratio| a fit may take (a ratio of 148 or 1/148): a fit that runs there says
the data see an all but rigid inclusion (or an all but empty one) and fix only a lower bound."""

_SYM = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))
"""Where the six entries of a symmetric 3 x 3 matrix's change sit (and their mirror images)."""


@dataclass(frozen=True)
class EllipsoidShape:
    """A fitted ellipsoidal region: ``centre (3,)``, semi-axes ``axes (3,)`` (larger first) along
    the columns of ``rotation (3, 3)``, modulus ``ratio`` times the background's (length unit)."""

    centre: tuple
    axes: tuple
    rotation: tuple
    ratio: float

    kind = "ellipsoid"

    @property
    def volume(self) -> float:
        return float(4.0 / 3.0 * np.pi * np.prod(self.axes))

    @property
    def cause(self) -> str:
        return "stiffer-region" if self.ratio > 1 else "softer-region"

    def describe(self) -> str:
        c, a = np.round(self.centre, 2).tolist(), np.round(self.axes, 2).tolist()
        return f"ellipsoid at {c}, semi-axes {a}, volume {self.volume:.1f}, x{self.ratio:.3g}"

    def moved(self, other: EllipsoidShape) -> float:
        """How far ``other`` lies from this one: the largest change of a centre coordinate or axis."""
        return float(np.abs(np.r_[np.subtract(self.centre, other.centre), np.subtract(self.axes, other.axes)]).max())


def sample_points(mesh, n: int = 6) -> Float[np.ndarray, "cells q 3"]:
    """Points of each cell at which the indicator is averaged: the points of a lattice of ``n``
    steps per edge of its corner tetrahedron, faces and corners included (84 for ``n = 6``), which
    spread over the whole cell (the lattice's interior points alone huddle round the centroid and
    overstate an ellipsoid's share)."""
    lam = np.array([(i, j, k, n - i - j - k) for i in range(n + 1) for j in range(n + 1 - i)
                    for k in range(n + 1 - i - j)], float) / n
    return np.einsum("qc,ncd->nqd", lam, mesh.nodes[mesh.cells[:, :4]])


def cell_size(mesh) -> float:
    """A cell's typical size (length unit): the side of the cube that six mean cells fill."""
    return float(np.cbrt(6.0 * mesh.volumes().mean()))


def cell_sizes(mesh) -> Float[np.ndarray, "cells"]:
    """``(n_cells,)``: each cell's size (length unit), the side of the cube six such cells fill (a
    graded mesh's vary: :mod:`refine.solid.inclusion_mesh`)."""
    return np.cbrt(6.0 * mesh.volumes())


@dataclass(frozen=True, eq=False)
class EllipsoidModulus:
    """The parametrisation of one ellipsoidal inclusion (see the module): started at ``centre0
    (3,)`` and ``M0 (3, 3)`` on ``mesh``, lengths in units of ``scale``, the indicator's ``width``
    (length unit: a number, or ``(n_cells, 1)`` per cell), a semi-axis kept above ``min_axis``, the start's log ratio ``log_ratio0``, the
    material's Poisson ratio ``nu``."""

    mesh: object
    centre0: np.ndarray
    M0: np.ndarray
    scale: float
    width: float
    min_axis: float
    log_ratio0: float
    nu: float
    samples: np.ndarray = field(default=None)

    def __post_init__(self):
        if self.samples is None:
            object.__setattr__(self, "samples", sample_points(self.mesh))

    size = 10

    @property
    def z0(self):
        return jnp.zeros(self.size).at[0].set(self.log_ratio0)

    def geometry(self, z, xp=jnp):
        """The log ratio, centre ``(3,)`` and matrix ``M (3, 3)`` at ``z``."""
        z = xp.asarray(z)
        d = z[4:10] * self.scale
        dM = xp.zeros((3, 3))
        for k, (i, j) in enumerate(_SYM):
            e = np.zeros((3, 3))
            e[i, j] = e[j, i] = 1.0
            dM = dM + d[k] * e
        return z[0], xp.asarray(self.centre0) + self.scale * z[1:4], xp.asarray(self.M0) + dM

    def fraction(self, z):
        """``(n_cells,)``: the smooth share of each cell inside the ellipsoid at ``z``."""
        _, c, M = self.geometry(z)
        # M^-1 by the closed form (its columns solve M x = e_i), not LAPACK in compiled code
        # (see jaxfem.probe.solve_small)
        Minv = solve_small(jnp.broadcast_to(M, (3, 3, 3)), jnp.eye(3)).T
        p = (jnp.asarray(self.samples) - c) @ Minv.T
        rho = jnp.sqrt(jnp.sum(p * p, -1) + 1e-12)
        grad = (p @ Minv) / rho[..., None]  # d rho / dx: a function of the direction from c alone
        # (rho^3 - 1) / 3 rather than rho - 1: the signed distance to first order all the same, but
        # the share then integrates to the ellipsoid's volume exactly along every ray from c (with
        # rho - 1 a curved surface's smoothing adds pi^2 (width / axis)^2 of it: 17 % at a fifth);
        # what is left, about exp(-k) / k with k = axis / (3 width), is 0.5 % at a width of a
        # tenth of the cell size and an axis of a cell
        d = (rho**3 - 1.0) / (3.0 * jnp.sqrt(jnp.sum(grad * grad, -1) + 1e-12))
        return jnp.mean(jax.nn.sigmoid(-d / self.width), axis=-1)  # stable far out, where rho^3 is large

    def apply(self, theta, z):
        return {**theta, "E": theta["E"] * mori_tanaka(self.fraction(z), jnp.asarray(z)[0], self.nu)}

    def regularization(self, z):
        return 0.0

    def shape(self, z) -> EllipsoidShape:
        """The ellipsoid at ``z``."""
        lr, c, M = self.geometry(np.asarray(z, float), np)
        w, V = np.linalg.eigh(0.5 * (M + M.T))
        return EllipsoidShape(tuple(map(float, c)), tuple(map(float, w[::-1])), tuple(map(tuple, V[:, ::-1])),
                              float(np.exp(lr)))

    def infeasibility(self, z) -> str | None:
        """Why the ellipsoid at ``z`` is not one to solve for (None: it is)."""
        if not np.isfinite(np.asarray(z, float)).all():
            return "the step is not a finite number"
        _, c, M = self.geometry(np.asarray(z, float), np)
        smallest = float(np.linalg.eigvalsh(M).min())
        if smallest <= self.min_axis:
            return f"a semi-axis would fall to {smallest:.3g}"
        lo, hi = self.mesh.bounds()
        if (c < lo).any() or (c > hi).any():
            return f"the centre would leave the body, at {np.round(c, 2).tolist()}"
        if abs(float(np.asarray(z)[0])) > MAX_LOG_RATIO:
            return f"the ratio would reach {np.exp(float(np.asarray(z)[0])):.3g}"
        return None

    def values(self, z) -> dict:
        s = self.shape(z)
        return {"inclusion": {"centre": list(s.centre), "axes": list(s.axes), "volume": s.volume,
                              "relative_elasticity": s.ratio}}


def mori_tanaka(f, log_ratio, nu: float):
    """``E* / E`` of a material holding the volume share ``f`` of spheres whose modulus is
    ``exp(log_ratio)`` times its own (the same ``nu``): the Mori-Tanaka estimate (the
    Hashin-Shtrikman bound with the background as matrix), exact at ``f = 0`` and ``f = 1``."""
    r = jnp.exp(log_ratio) - 1.0
    K1, G1 = 1.0 / (3.0 * (1.0 - 2.0 * nu)), 1.0 / (2.0 * (1.0 + nu))
    F1 = G1 * (9.0 * K1 + 8.0 * G1) / (6.0 * (K1 + 2.0 * G1))
    K = K1 + f * r * K1 / (1.0 + (1.0 - f) * r * K1 / (K1 + 4.0 / 3.0 * G1))
    G = G1 + f * r * G1 / (1.0 + (1.0 - f) * r * G1 / (G1 + F1))
    return 9.0 * K * G / (3.0 * K + G)


QUANTITIES = ("cx", "cy", "cz", "a", "b", "c", "volume", "ratio")
"""What :func:`ellipsoid_errors` gives standard errors of, in this order."""


def quantities(shape: EllipsoidShape) -> np.ndarray:
    """``(8,)``: :data:`QUANTITIES` of a shape."""
    return np.array([*shape.centre, *shape.axes, shape.volume, shape.ratio])


@dataclass(frozen=True, eq=False)
class Inclusion:
    """The hypothesis of one ellipsoidal inclusion in ``model``, started at ``centre``, semi-axes
    ``axes (3,)`` along the columns of ``rotation (3, 3)`` and ``ratio`` (a
    :class:`~refine.diagnosis.fitted.Hypothesis`; nothing to remesh)."""

    model: MeasuredModel
    centre: tuple
    axes: tuple
    rotation: tuple
    ratio: float
    remeshable = False

    @classmethod
    def from_blob(cls, model: MeasuredModel, blob, shrink: float = 0.8, min_ratio: float = 2.0) -> Inclusion:
        """Started at a field's region (:class:`refine.solid.field.Blob`): its moment ellipsoid
        shrunk by ``shrink`` (a smoothed field spreads a region), its ratio pushed at least to
        ``min_ratio`` (or below its inverse; smoothing also flattens the peak)."""
        r = blob.ratio ** 1.5
        r = max(r, min_ratio) if blob.sign > 0 else min(r, 1.0 / min_ratio)
        return cls(model, tuple(blob.centroid), tuple(shrink * blob.axes), tuple(map(tuple, blob.rotation)), float(r))

    @property
    def law(self) -> str:
        return self.model.experiment.law

    def build(self) -> tuple[Compiled, np.ndarray]:
        mesh = self.model.mesh
        R = np.asarray(self.rotation, float)
        M0 = R @ np.diag(self.axes) @ R.T
        sizes = cell_sizes(mesh)
        # the unknowns' unit and the least semi-axis from the cells where the ellipsoid starts (a
        # graded mesh's fine ones), the indicator's width from each cell's own size
        local = (mesh.centroids() - np.asarray(self.centre, float)) @ R / np.asarray(self.axes, float)
        within = (local**2).sum(1) <= 1.0
        h = float(np.median(sizes[within])) if within.any() else cell_size(mesh)
        param = EllipsoidModulus(mesh, np.asarray(self.centre, float), M0, 0.5 * h, 0.1 * sizes[:, None], 0.25 * h,
                                 float(np.log(self.ratio)), float(self.model.experiment.nu))
        return Compiled(self.model, param), np.asarray(param.z0)

    def shapes_at(self, compiled: Compiled, z) -> tuple[EllipsoidShape]:
        return (compiled.param.shape(z),)

    def cause_of(self, shapes) -> str:
        return shapes[0].cause if shapes else "none"

    def at(self, shapes, element):
        return None

    def on(self, model: MeasuredModel, shapes) -> Inclusion:
        """The same hypothesis in another ``model`` of the body (e.g. a finer mesh), started at
        the fitted ``shapes``."""
        s = shapes[0]
        return type(self)(model, tuple(s.centre), tuple(s.axes), tuple(map(tuple, np.asarray(s.rotation))), float(s.ratio))


def ellipsoid_errors(fitted, step: float = 1e-6) -> dict | None:
    """Standard errors of the fitted region's centre, axes, volume and ratio (any parametrisation
    whose ``shape(z)`` has ``centre``, ``axes``, ``volume`` and ``ratio``: an ellipsoid, a box, a cavity; (the delta method
    on ``fitted.z_cov`` through :meth:`EllipsoidModulus.shape`, central differences), as
    report.json lists them; None without a covariance."""
    cov = getattr(fitted, "z_cov", None)
    if cov is None or fitted.compiled is None:
        return None
    param, z = fitted.compiled.param, np.asarray(fitted.z, float)
    G = np.zeros((len(QUANTITIES), z.size))
    for j in range(z.size):
        dz = np.zeros_like(z)
        dz[j] = step * max(1.0, abs(z[j]))
        G[:, j] = (quantities(param.shape(z + dz)) - quantities(param.shape(z - dz))) / (2 * dz[j])
    var = np.einsum("qk,kl,ql->q", G, cov, G)
    std = [None if not np.isfinite(v) else round(float(np.sqrt(max(v, 0.0))), 4) for v in var]
    return {"centroid": std[:3], "axes": std[3:6], "volume": std[6], "relative_elasticity": std[7]}
