"""Gaps in the tracked points inside the domain (2D): a hole has no material points, so nothing
can be tracked there (:func:`refine.diagnosis.candidates.missing_point_regions`, the
``cfg.max_regions`` largest; softer candidates of source ``"missing-points"``). Listed first."""

from __future__ import annotations

from refine.causes.sources.registry import Source, register_source
from refine.diagnosis.candidates import missing_point_regions


def find(look, found=None) -> list:
    obs = look.model.obs
    return missing_point_regions(obs.reference, look.model.experiment.domain)[:look.cfg.max_regions]


SOURCE = register_source(Source("gaps", {2}, find, order=10, doc="gaps in the tracked points inside the domain"))
