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
from refine.model.shape_geometry import ShapeGeometry, make_shape

__all__ = ["RegionModuli", "ModulusField", "Combined", "ShapeGeometry", "UniformParameter", "make_shape",
           "infeasibility", "cell_adjacency", "MAX_LOG_RATIO", "bounded_exp"]


MAX_LOG_RATIO = 30.0
"""The largest log modulus ratio :class:`RegionModuli` takes (a ratio of about 1e13 either way):
an optimiser's step beyond it is refused (:meth:`RegionModuli.infeasibility`)."""


def bounded_exp(z):
    """``exp(z)`` of log ratios, the exponent clipped to what a float64 holds (no overflow: a
    ratio drawn far beyond any fit reads as about 1e304, not inf with a warning)."""
    return np.exp(np.clip(np.asarray(z, float), -700.0, 700.0))


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

    def infeasibility(self, z) -> str | None:
        """Why the log moduli ``z`` are not taken (None: they are): not finite, or beyond
        :data:`MAX_LOG_RATIO` (a modulus ratio of about 1e13 either way: a fit that runs there
        has lost the region; its ``exp`` would soon overflow)."""
        z = np.asarray(z, float)
        if not np.all(np.isfinite(z)):
            return "a log modulus would not be finite"
        if z.size and np.abs(z).max() > MAX_LOG_RATIO:
            return f"a log modulus would reach {z[np.argmax(np.abs(z))]:.3g} (bound {MAX_LOG_RATIO:g})"
        return None

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
