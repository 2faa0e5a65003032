"""Where the measured strain map departs from the initial model's (2D), in the frame of most
motion (:func:`refine.diagnosis.candidates.strain_regions`: the paper reads a scar as a pocket of
low measured strain, a hole as one of high strain), the ``cfg.strain_candidates`` strongest
(none where 0), less those at a noisy edge that the edge's own noise explains
(:func:`refine.diagnosis.candidates.edge_artefact`); source ``"strain"``."""

from __future__ import annotations

import numpy as np

from refine.causes.sources.registry import Source, register_source
from refine.diagnosis.candidates import edge_artefact, strain_regions


def find(look, found=None) -> list:
    model, cfg, obs = look.model, look.cfg, look.model.obs
    if cfg.strain_candidates <= 0:
        return []
    k = int(np.nanargmax(np.nanmedian(np.linalg.norm(obs.displacements, axis=2), axis=1)))
    seen = (look.fit | (obs.roles == "boundary")) & obs.valid[k]  # no held-out point proposes a place
    strain = strain_regions(obs.reference[seen], obs.displacements[k, seen], look.predicted[k, seen], look.sigma,
                            min_area=2.0 * model.spacing**2, max_regions=cfg.strain_candidates)
    residuals = look.residuals
    return [c for c in strain if not edge_artefact(c, obs, residuals, look.fit, model.experiment.domain,
                                                   model.spacing, look.sigma)]


SOURCE = register_source(Source("strain", {2}, find, order=40,
                                doc="the measured strain map's departures from the initial model's"))
