"""Absolute or relative moduli: what a measured force adds (the paper's Sec. 2.2, eqs. 7-8).

A plane-stress sheet whose boundary motion is prescribed (the measured set P) responds to the
product E b of modulus and thickness only through its ratios: multiplying every E b by the same
factor leaves every displacement unchanged. Displacements alone therefore determine the
relative elasticity E_R = (E2 b2) / (E1 b1) of each region (eq. 8) and nothing absolute; E and b
are confounded (eq. 7). A force measured across a side of the domain (a load cell; the bundle's
forces.csv) is proportional to E b, so with it the background's E b is absolute, and with the
assumed thickness b so is E.

- :class:`ForcedObjective`: the displacement misfit plus force residuals, the predicted force
  being the sum of the model's reactions on the nodes of that side.
- :class:`Elasticity`: what was identified: relative elasticity always, moduli only with forces;
  asking for a modulus that the data cannot fix raises :class:`IdentifiabilityError`.
- :func:`fit_region_moduli`: fits regions (and, with forces, the background) and says which.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from refine.exceptions import IdentifiabilityError
from refine.model.objective import Objective
from refine.optimize.least_squares import least_squares
from refine.model.measured import MeasuredModel
from refine.model.parametrize import RegionModuli
from refine.optimize.result import RefineResult

RELATIVE_ONLY = (
    "only relative elasticity E_R = (E2 b2)/(E1 b1) (eq. 8) is identifiable without a measured force: "
    "for a plane-stress sheet driven by its measured boundary the displacements depend on modulus x "
    "thickness only through ratios, so E and the thickness b are confounded and no absolute modulus "
    "can be given. Add a measured force (forces.csv, e.g. a load cell on one side) to fix E b."
)


def side_force(model: MeasuredModel, theta, U, nodes):
    """Force across a side in every frame, ``(n_frames, dim)``: the sum of the reactions that hold
    the side's ``nodes`` at their measured positions, for displacements ``U (n_frames, ...)``."""
    return jax.vmap(lambda u: model.solver.reactions(u, theta, nodes))(U)


class ForcedObjective(Objective):
    """:class:`~refine.model.Objective` with the measured force across one side as extra residuals.

    Args:
        model: the measured model; its bundle must carry forces on ``edge``.
        param: a parametrisation; fit the background too (``RegionModuli(background=True)``),
            since only the force can fix it.
        edge: the side the force was measured on (a rectangle's ``"right"``, ``"left"``,
            ``"bottom"``, ``"top"``, or a side the domain names: :mod:`refine.bundle.sides`).
        force_std: standard deviation of each measured force component, force unit (default: 1 %
            of the largest measured force, a typical load cell).
        **kw: as :class:`~refine.model.Objective` (``theta``, ``role``, ``points``, ``noise_std``).

    Raises:
        IdentifiabilityError: the bundle has no force on ``edge``.
    """

    def __init__(self, model: MeasuredModel, param, edge: str = "right", force_std: float | None = None, **kw):
        super().__init__(model, param, **kw)
        forces = model.obs.forces
        if forces is None or edge not in forces.edges:
            raise IdentifiabilityError(f"the bundle has no measured force on the {edge!r} side, so " + RELATIVE_ONLY)
        self.edge = edge
        self.nodes = model.sides[edge]  # the domain's named side (refine.model.boundary.side_nodes)
        if not np.isin(self.nodes, model.loop).all():
            raise IdentifiabilityError(f"the {edge!r} side of the mesh is not driven by boundary points, so "
                                       "its reaction is not the force across it")
        self.measured_force = jnp.asarray(forces.on(edge))  # (frames, dim)
        scale = float(np.abs(forces.on(edge)).max())
        self.force_sigma = float(force_std) if force_std else 0.01 * scale

    @property
    def n_residuals(self) -> int:
        return super().n_residuals + int(np.prod(self.measured_force.shape))

    def predicted_force(self, theta, U):
        """Force across ``edge`` in every frame, ``(n_frames, dim)``: the sum of the reactions that
        hold the side's nodes at their measured positions."""
        return side_force(self.model, theta, U, self.nodes)

    def residuals(self, z):
        """Displacement residuals (noise units) followed by the force residuals ``(frames * dim,)``."""
        theta = self.param.apply(self.theta, z)
        U = self.model.solve_frames(theta)
        r = self.residuals_of(self.model.at_points(U, theta))
        rf = (self.predicted_force(theta, U) - self.measured_force) / self.force_sigma
        return jnp.concatenate([r, rf.reshape(-1)])


@dataclass(frozen=True)
class Elasticity:
    """Identified elasticity of a set of regions.

    Attributes:
        relative: region name -> relative elasticity E_R = (E b)_region / (E b)_background (eq. 8).
        background_modulus: the background's E in stress units when a force fixed it, else None.
        thickness: the assumed thickness b that absolute moduli refer to (what the force fixes is
            E b; another b gives E b / b).
        note: a sentence for a report: why moduli are or are not absolute.
    """

    relative: dict
    background_modulus: float | None
    thickness: float
    note: str

    @property
    def absolute(self) -> bool:
        """Whether absolute moduli are identifiable (a force was measured and fitted)."""
        return self.background_modulus is not None

    def modulus(self, region: str | None = None) -> float:
        """Absolute modulus of ``region`` (of the background when None), stress units.

        Raises:
            IdentifiabilityError: no force was measured; only :attr:`relative` is known.
        """
        if self.background_modulus is None:
            raise IdentifiabilityError("no force was measured, so " + RELATIVE_ONLY)
        return self.background_modulus * (1.0 if region is None else self.relative[region])


def fit_region_moduli(model: MeasuredModel, masks, names=(), *, edge: str = "right", force_std=None,
                      use_forces: bool | None = None, method: str = "lm", rtol: float = 1e-5,
                      atol: float = 1e-4, progress: bool = False) -> tuple[Elasticity, RefineResult]:
    """Fit one modulus per region by least squares; absolute if the bundle has a force, else relative.

    Args:
        model: the measured model.
        masks: ``(n_regions, n_cells)`` region membership.
        names: one name per region.
        edge: the side whose measured force is matched.
        force_std: see :class:`ForcedObjective`.
        use_forces: force the choice (default: use forces when the bundle has them on ``edge``).
        method, rtol, atol, progress: of :func:`refine.optimize.least_squares`.

    Returns:
        ``(elasticity, result)``: the identified :class:`Elasticity` and the fit's record.
    """
    forces = model.obs.forces
    have = forces is not None and edge in forces.edges
    use = have if use_forces is None else use_forces
    E0 = model.experiment.E
    param = RegionModuli(masks=masks, E0=E0, names=tuple(names), background=use)
    objective = ForcedObjective(model, param, edge, force_std) if use else Objective(model, param)
    result = least_squares(objective, method=method, rtol=rtol, atol=atol, progress=progress)
    z = np.asarray(result.values["z"])
    zr = z[1:] if use else z
    relative = {n: float(np.exp(v)) for n, v in zip(param.names, zr)}
    thickness = model.experiment.thickness or 1.0
    if use:
        note = (f"absolute: the force measured on the {edge} side fixes E b; moduli assume the thickness "
                f"b = {thickness:g}")
        return Elasticity(relative, float(E0 * np.exp(z[0])), thickness, note), result
    return Elasticity(relative, None, thickness, "relative: no force was measured, so " + RELATIVE_ONLY), result


@dataclass(frozen=True)
class ForceScale:
    """The factor on every modulus that makes a fitted model's reactions match the measured forces.

    Under measured boundary motion the displacements do not depend on a common factor s on every
    modulus, while the reactions are proportional to it (every law here is linear in E at fixed
    nu), so the least-squares s over every frame, side and component is one division:
    s = sum(F_measured . F_model) / sum(F_model . F_model).

    Attributes:
        scale: s; the model's moduli times s are absolute (for the assumed thickness).
        relative_residual: |F_measured - s F_model| / |F_measured| over everything matched: how
            well one factor explains the forces (a large value: the model's shape of the force
            history is wrong, e.g. the law).
        edges: the sides that were used.
    """

    scale: float
    relative_residual: float
    edges: tuple


def force_scale(model: MeasuredModel, theta) -> ForceScale | None:
    """Fit :class:`ForceScale` for a model with parameters ``theta`` (None when the bundle has
    no force on a side the model's boundary drives)."""
    forces = model.obs.forces
    if forces is None:
        return None
    edges = []
    for edge in forces.edges:  # every side is defined (the model refuses a force on an undefined one)
        nodes = model.sides[edge]
        if len(nodes) and np.isin(nodes, model.loop).all():
            edges.append((edge, nodes))
    if not edges:
        return None
    U = model.solve_frames(theta)
    # one compiled function per side: called eagerly, every JAX operation compiles on its own
    pred = np.stack([np.asarray(jax.jit(lambda th, UU: side_force(model, th, UU, nodes))(theta, U))
                     for _, nodes in edges], 1)  # (frames, edges, dim)
    meas = np.stack([forces.on(e) for e, _ in edges], 1)
    s = float(np.sum(meas * pred) / np.sum(pred * pred))
    rel = float(np.linalg.norm(meas - s * pred) / np.linalg.norm(meas))
    return ForceScale(s, rel, tuple(e for e, _ in edges))
