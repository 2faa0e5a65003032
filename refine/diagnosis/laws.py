"""Another homogeneous material law, its Poisson's ratio (and any extra parameter) fitted, and the
fitted law's parameters with their standard errors."""

from __future__ import annotations

from dataclasses import dataclass, replace

import jax
import jax.numpy as jnp
import numpy as np

from jaxfem.materials import LAWS, alternatives, get_material

from refine.diagnosis.fitted import Fitted, fit_compiled, material_law
from refine.measures import Residuals
from refine.model.measured import MeasuredModel
from refine.model.objective import Compiled
from refine.model.parametrize import Combined, UniformParameter

#: law -> the laws a diagnosis tries instead, in order (derived from jaxfem's registry:
#: :func:`jaxfem.materials.alternatives`)
ALTERNATIVE_LAWS = {law: alternatives(law) for law in LAWS}

ANGLE_STARTS = 6
"""How many starts over one period an angle-like parameter (a fibre direction) is tried from
before its fit: the misfit is stationary in the angle wherever the angle meets a symmetry of the
loading (fibres along or across the pull), so a single start may never move."""


@dataclass(frozen=True, eq=False)
class AngleParameter:
    """An angle uniform over the body (radians), defined modulo ``period``: unbounded, ``value =
    z`` (no bounds to saturate at; :func:`law_parameters` reports it wrapped into one period)."""

    key: str
    start: float
    period: float

    @property
    def size(self) -> int:
        return 1

    @property
    def z0(self):
        return jnp.array([self.start], float)

    def value(self, z):
        return jnp.asarray(z)[0]

    def apply(self, theta, z):
        return {**theta, self.key: jnp.full_like(theta[self.key], self.value(z))}

    def regularization(self, z):
        return 0.0

    def values(self, z) -> dict:
        v = float(self.value(z))
        return {self.key: v - self.period * np.floor(v / self.period + 0.5)}


def law_parts(law: str, nu: float, start: dict | None = None) -> tuple:
    """The parametrisations of a law's fitted parameters: Poisson's ratio, then each extra the law
    fits (:attr:`jaxfem.materials.Parameter.fit`), from ``start`` (name -> value) or their
    defaults; an angle-like extra (with a ``period``) as an :class:`AngleParameter`."""
    start = start or {}
    parts = [UniformParameter("nu", float(np.clip(start.get("nu", nu), 0.005, 0.494)), 0.0, 0.499)]
    for q in get_material(law).extra:
        if not q.fit:
            continue
        s = float(start.get(q.name, q.default))
        if q.period:
            parts.append(AngleParameter(q.name, s, q.period))
        else:
            margin = 0.01 * (q.upper - q.lower)
            parts.append(UniformParameter(q.name, float(np.clip(s, q.lower + margin, q.upper - margin)), q.lower, q.upper))
    return tuple(parts)


def best_angle_start(compiled: Compiled, fit_mask, sigma: float) -> np.ndarray:
    """The unknowns ``z`` to start a fit from: the parametrisation's start with each angle
    (:class:`AngleParameter`, one at a time) moved to the best of :data:`ANGLE_STARTS` values over
    its period, by the misfit on ``fit_mask`` (one forward solve each)."""
    at = Residuals.at(compiled.model.obs.displacements, fit_mask, sigma)
    z = np.asarray(compiled.param.z0, float)
    i = 0
    for part in getattr(compiled.param, "parts", (compiled.param,)):
        if isinstance(part, AngleParameter):
            tries = []
            for j in range(ANGLE_STARTS):
                zj = z.copy()
                zj[i] = part.start + part.period * j / ANGLE_STARTS
                r = at(compiled.predict(zj))
                tries.append((float(np.sum(r * r)) if np.isfinite(r).all() else np.inf, zj))
            z = min(tries, key=lambda t: t[0])[1]
        i += part.size
    return z


def fit_law(base: MeasuredModel, law: str, fit_mask, hold_mask, sigma) -> Fitted:
    """A different homogeneous material law, with its Poisson's ratio and the law's extra
    parameters (its :attr:`jaxfem.Material.extra` that it fits, from their defaults within their
    bounds; an angle from the best of a few starts, :func:`best_angle_start`) fitted."""
    ex = replace(base.experiment, law=law, parameters={})  # the initial law's extra parameters are not this law's
    model = MeasuredModel(ex, base.obs, mesh=base.mesh, h=base.h, linear_solver=base.linear_solver)
    compiled = Compiled(model, Combined(law_parts(law, float(ex.nu))))
    return fit_compiled(material_law(law), compiled, fit_mask, hold_mask, sigma,
                        z0=best_angle_start(compiled, fit_mask, sigma))


def law_parameters(f: Fitted) -> dict:
    """The fitted law's parameters (those its fit took as unknowns: Poisson's ratio and the law's
    fitted extras) as ``{name: {"value": v, "std": s}}``: ``s`` the standard error (delta method
    on ``f.z_cov``; None before :func:`~refine.diagnosis.fitted.refit`), an angle in radians
    wrapped into one period. Empty for a fit without law unknowns."""
    param = getattr(getattr(f, "compiled", None), "param", None)
    if param is None or getattr(f, "z", None) is None:
        return {}
    parts = getattr(param, "parts", (param,))
    out, i = {}, 0
    for part in parts:
        if isinstance(part, (UniformParameter, AngleParameter)):
            zi = jnp.asarray(f.z[i:i + 1], float)
            value = part.values(np.asarray(zi))[part.key]
            std = None
            if f.z_cov is not None and np.isfinite(f.z_cov[i, i]):
                slope = float(jax.grad(lambda zz: part.value(zz))(zi)[0])
                std = abs(slope) * float(np.sqrt(max(f.z_cov[i, i], 0.0)))
            out[part.key] = {"value": float(value), "std": std}
        i += part.size
    return out
