"""The fitted modulus field's regions (2D): connected cells of abnormal log modulus
(:func:`refine.diagnosis.localize.segment`, those of at least a fifth of the strongest's
strength), those of one sign a point spacing apart joined
(:func:`refine.diagnosis.candidates.joined`), less those at a noisy edge that the edge's own
noise explains (:func:`refine.diagnosis.candidates.edge_artefact`); source ``"field"``."""

from __future__ import annotations

from refine.causes.sources.registry import Source, register_source
from refine.diagnosis.candidates import edge_artefact, joined
from refine.diagnosis.localize import segment


def find(look, found=None) -> list:
    model, cfg = look.model, look.cfg
    field = segment(model.mesh, look.field, min_area=0.5 * model.spacing**2, max_regions=cfg.max_regions)
    field = [c for c in field if c.strength >= 0.2 * field[0].strength] if field else []
    field = joined(field, model.mesh, model.spacing)
    residuals = look.residuals
    return [c for c in field if not edge_artefact(c, model.obs, residuals, look.fit, model.experiment.domain,
                                                  model.spacing, look.sigma)]


SOURCE = register_source(Source("field", {2}, find, order=30, doc="the fitted modulus field's regions"))
