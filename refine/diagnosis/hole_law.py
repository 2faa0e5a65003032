"""A hole in a material of another law: the hole's geometry and the law's parameters fitted
together. Where a hole alone leaves misfit beyond the noise, the material around it may not be
the initial model's (a laminate is orthotropic: its strain concentration at a hole differs from
an isotropic plate's, and an isotropic model matches it with a hole of the wrong size, or with a
zero-stiffness region over the hole and the ring of material around it)."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from refine.diagnosis.fitted import Fitted, fit, fit_compiled, material_law
from refine.diagnosis.holes import HoleHypothesis, hole_hypothesis, subset_start
from refine.diagnosis.laws import best_angle_start, law_parameters, law_parts
from refine.diagnosis.shapes import Hole
from refine.model.measured import MeasuredModel
from refine.model.objective import Compiled
from refine.model.parametrize import Combined


@dataclass(frozen=True, eq=False)
class HoleWithLaw(HoleHypothesis):
    """A hole (:class:`~refine.diagnosis.holes.HoleHypothesis`: ``base`` the initial model,
    ``hole`` the start) in a material of ``other_law``, the law's parameters
    (:func:`~refine.diagnosis.laws.law_parts`, from ``start``: name -> value, e.g. the law fitted
    with the hole held) fitted beside the hole's centre, axes and orientation. Unknowns: the
    hole's five first, then the law's. ``base`` and ``h`` are replaceable as a hole's (a fit moved
    onto every frame, a coarser mesh for the discretisation error): the law is carried here."""

    other_law: str = "fibre-reinforced"
    start: tuple = ()

    @property
    def law(self) -> str:
        return self.other_law

    def hole_only(self) -> HoleHypothesis:
        """The same hole, its geometry the only unknowns, in a material of ``other_law``."""
        return HoleHypothesis(with_law(self.base, self.other_law), self.hole, self.h, self.element, self.subsets)

    def build(self) -> tuple[Compiled, None]:
        compiled, _ = self.hole_only().build()
        param = Combined((compiled.param, *law_parts(self.law, float(compiled.model.experiment.nu), dict(self.start))))
        return Compiled(compiled.model, param), None

    def shapes_at(self, compiled: Compiled, z) -> tuple[Hole]:
        g = np.asarray(compiled.param.parts[0].shape_params(np.asarray(z)[:5]))[0]
        return (Hole((g[0], g[1]), (g[2], g[3]), g[4]),)

    def at(self, shapes, element: str) -> HoleWithLaw:
        moved = hole_hypothesis(self.base, shapes[0], h=self.h, element=element, subsets=self.subsets)
        return replace(self, hole=moved.hole, element=element)


def with_law(base: MeasuredModel, law: str) -> MeasuredModel:
    """``base`` with its material following ``law`` (the law's extras at their defaults)."""
    ex = replace(base.experiment, law=law, parameters={})
    return MeasuredModel(ex, base.obs, mesh=base.mesh, h=base.h, linear_solver=base.linear_solver)


def law_at_hole(hypothesis: HoleWithLaw, fit_mask, hold_mask, sigma) -> Fitted:
    """The law's parameters fitted with the hole held where ``hypothesis`` starts it (the angle
    from the best of a few starts, :func:`~refine.diagnosis.laws.best_angle_start`): the start of
    the joint fit. A hole started at the subsets' walls cannot move outward, and a joint step that
    pushes it there is turned down whole, so a joint fit from the law's defaults can stall with
    the law barely moved (the CFRP coupon: fibre stiffness 1.0 -> 1.01)."""
    compiled, _ = hypothesis.hole_only().build()
    law_only = Compiled(compiled.model, Combined(law_parts(hypothesis.law, float(compiled.model.experiment.nu))))
    return fit_compiled(material_law(hypothesis.law), law_only, fit_mask, hold_mask, sigma,
                        z0=best_angle_start(law_only, fit_mask, sigma))


def fit_hole_with_law(base: MeasuredModel, shape, law: str, fit_mask, hold_mask, sigma, start: dict | None = None,
                      h: float | None = None, element: str = "tri3") -> Fitted:
    """A hole started at ``shape`` (a fitted hole's, or a candidate's) in a material of ``law``,
    its geometry and the law's parameters fitted together; the law from ``start`` (name ->
    value) where given, else the better (lower misfit) of two joint fits: from the law fitted
    with the hole held at its start (:func:`law_at_hole`), and from the law's defaults (its
    angle from the best of a few starts, :func:`~refine.diagnosis.laws.best_angle_start`). A hole
    at the subsets' walls stalls from the defaults; a hole started well inside its true outline,
    free to grow, can do better from them, the law held at the small hole having made up for its
    size. With the bundle's subset known, the hole starts where the subsets put it
    (:func:`~refine.diagnosis.holes.subset_start`) and keeps out of every tracked subset, as
    :func:`~refine.diagnosis.holes.fit_hole`'s second fit does."""
    shape = subset_start(base, shape)
    held = hole_hypothesis(base, shape, h, element)
    hypothesis = HoleWithLaw(held.base, held.hole, held.h, held.element, held.subsets, law)
    if start:
        fitted = fit(replace(hypothesis, start=tuple(start.items())), fit_mask, hold_mask, sigma)
    else:
        from_held = fit(replace(hypothesis, start=tuple(starts_from(law_at_hole(hypothesis, fit_mask, hold_mask,
                                                                               sigma)).items())),
                        fit_mask, hold_mask, sigma)
        compiled, _ = hypothesis.build()
        from_defaults = fit_compiled(hypothesis, compiled, fit_mask, hold_mask, sigma,
                                     z0=best_angle_start(compiled, fit_mask, sigma))
        fitted = min((from_held, from_defaults), key=lambda f: f.chi2_fit if np.isfinite(f.chi2_fit) else np.inf)
    # a remesh (refit) starts the law where this fit left it, not where this fit started
    return replace(fitted, hypothesis=replace(fitted.hypothesis, start=tuple(starts_from(fitted).items())))


def starts_from(f: Fitted) -> dict:
    """The fitted values of a law's parameters (:func:`~refine.diagnosis.laws.law_parameters`),
    as starts for another fit of the same law."""
    return {k: v["value"] for k, v in law_parameters(f).items()}


def hole_law_jobs(model: MeasuredModel, tried: list[Fitted], fit_mask, hold_mask, sigma) -> dict:
    """The "hole + law" hypothesis as a job for the diagnosis's search (name -> a function of
    nothing that fits it; empty where it does not apply): the best hole fitted so far in
    ``tried``, refitted in a material of the alternative law that fitted best alone (the lowest
    misfit among ``tried``'s material laws), the law and the hole together
    (:func:`fit_hole_with_law`). It applies only where both a hole and another law were tried,
    i.e. a hole was possible (no material seen inside) and no region or hole explained the data:
    a hole whose neighbourhood the initial law gets wrong (a laminate's strain concentration)
    is then told from a soft region over the hole and the ring of material around it, which
    is what an isotropic model fits instead."""
    holes = [f for f in tried if f.cause == "hole"]
    laws = [f for f in tried if f.cause == "material-law"]
    if not holes or not laws:
        return {}
    hole = min(holes, key=lambda f: f.bic + f.chi2_holdout).shapes[0]
    law = min(laws, key=lambda f: f.chi2_fit).law
    return {f"hole with {law}": lambda: fit_hole_with_law(model, hole, law, fit_mask, hold_mask, sigma)}
