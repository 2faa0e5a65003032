"""Holes where a gap and another source's softer candidate coincide (2D): in each softer
candidate that is not itself a gap, the widest empty disc of the points, where the layout's
density would rarely leave one as wide (:func:`refine.diagnosis.candidates.soft_gaps`; source
``"missing-points"``). A hole nobody modelled in a thinned export leaves a gap too narrow to
stand out on its own. It reads the other sources' candidates; listed after the gaps."""

from __future__ import annotations

from refine.causes.sources.registry import Source, register_source
from refine.diagnosis.candidates import soft_gaps


def find(look, found) -> list:
    others = [c for cs in found.values() for c in cs if c.source != "missing-points"]
    return soft_gaps(look.model.obs.reference, look.model.experiment.domain, others)


SOURCE = register_source(Source("soft-gaps", {2}, find, order=20, reads=True,
                                doc="a narrower gap inside another source's softer candidate"))
