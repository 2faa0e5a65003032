"""A hole in a material of another law: the hole's geometry and the law's parameters fitted
together. Where a hole alone leaves misfit beyond the noise, the material around it may not be
the initial model's (a laminate is orthotropic: its strain concentration at a hole differs from
an isotropic plate's, and an isotropic model matches it with a hole of the wrong size)."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from refine.diagnosis.fitted import Fitted, fit, fit_compiled
from refine.diagnosis.holes import HoleHypothesis, hole_hypothesis, subset_start
from refine.diagnosis.laws import best_angle_start, law_parameters, law_parts
from refine.diagnosis.shapes import Hole
from refine.model.measured import MeasuredModel
from refine.model.objective import Compiled
from refine.model.parametrize import Combined


@dataclass(frozen=True, eq=False)
class HoleWithLaw:
    """A hole (``hole``: a :class:`~refine.diagnosis.holes.HoleHypothesis` whose base model
    follows ``law``) with the law's parameters (:func:`~refine.diagnosis.laws.law_parts`, from
    ``start``: name -> value, e.g. the law fitted alone) fitted beside its centre, axes and
    orientation. Unknowns: the hole's five first, then the law's."""

    hole: HoleHypothesis
    start: tuple = ()
    remeshable = True

    @property
    def law(self) -> str:
        return self.hole.law

    def build(self) -> tuple[Compiled, None]:
        compiled, _ = self.hole.build()
        param = Combined((compiled.param, *law_parts(self.law, float(compiled.model.experiment.nu), dict(self.start))))
        return Compiled(compiled.model, param), None

    def shapes_at(self, compiled: Compiled, z) -> tuple[Hole]:
        g = np.asarray(compiled.param.parts[0].shape_params(np.asarray(z)[:5]))[0]
        return (Hole((g[0], g[1]), (g[2], g[3]), g[4]),)

    def cause_of(self, shapes) -> str:
        return "hole"

    def at(self, shapes, element: str) -> HoleWithLaw:
        return replace(self, hole=hole_hypothesis(self.hole.base, shapes[0], h=self.hole.h, element=element))


def with_law(base: MeasuredModel, law: str) -> MeasuredModel:
    """``base`` with its material following ``law`` (the law's extras at their defaults)."""
    ex = replace(base.experiment, law=law, parameters={})
    return MeasuredModel(ex, base.obs, mesh=base.mesh, h=base.h, linear_solver=base.linear_solver)


def fit_hole_with_law(base: MeasuredModel, shape, law: str, fit_mask, hold_mask, sigma, start: dict | None = None,
                      h: float | None = None, element: str = "tri3") -> Fitted:
    """A hole started at ``shape`` (a fitted hole's, or a candidate's) in a material of ``law``,
    its geometry and the law's parameters fitted together; the law's angle (where it has one)
    from the best of a few starts unless ``start`` gives it (:func:`best_angle_start`). With the
    bundle's subset known, the hole starts where the subsets put it
    (:func:`~refine.diagnosis.holes.subset_start`) and keeps out of every tracked subset, as
    :func:`~refine.diagnosis.holes.fit_hole`'s second fit does."""
    shape = subset_start(base, shape)
    hypothesis = HoleWithLaw(hole_hypothesis(with_law(base, law), shape, h, element), tuple((start or {}).items()))
    if start:
        fitted = fit(hypothesis, fit_mask, hold_mask, sigma)
    else:
        compiled, _ = hypothesis.build()
        fitted = fit_compiled(hypothesis, compiled, fit_mask, hold_mask, sigma,
                              z0=best_angle_start(compiled, fit_mask, sigma))
    # a remesh (refit) starts the law where this fit left it, not at its defaults
    return replace(fitted, hypothesis=replace(hypothesis, start=tuple(starts_from(fitted).items())))


def starts_from(f: Fitted) -> dict:
    """The fitted values of a law's parameters (:func:`~refine.diagnosis.laws.law_parameters`),
    as starts for another fit of the same law."""
    return {k: v["value"] for k, v in law_parameters(f).items()}
