"""A hole in a sheet (2D): an ellipse removed from the domain, its centre, axes and orientation
fitted (:func:`refine.diagnosis.holes.fit_hole`). Two plug-ins: ``"hole"`` (a ``"place"`` cause:
at a softer candidate, when it is the first region; job ``"hole"``) and ``"hole-from-region"`` (a
``"reshape"`` cause: the hole fitted again from a very soft region's fitted outline where the
first hole fit may have settled badly from the candidate's rough one; job ``"hole from
region"``). Both name ``"hole"``."""

from __future__ import annotations

from refine.causes.registry import Cause, register
from refine.diagnosis.holes import fit_hole


def jobs(search, start) -> dict:
    """A hole at the softer candidate ``start`` where no region was found before it (nothing
    otherwise: a hole is never added to a region)."""
    if start.sign >= 0 or search.used:
        return {}
    shape = search.shape(None)
    return {"hole": lambda: fit_hole(search.model, shape, search.fit, search.hold, search.sigma)}


def from_region(search, start) -> dict:
    """The hole again from the outline of ``start``, a softer region fitted at a candidate where
    a hole was tried (the job ``"hole"`` among ``search.fits``) and whose ratio is below
    ``cfg.hole_below``, unless the first hole fit was far off (BIC no worse than the region's,
    or a misfit over twice the region's: the outline is not it)."""
    if not ("hole" in search.fits and start.cause == "softer-region" and start.shapes[0].ratio < search.cfg.hole_below):
        return {}
    hole = search.fits["hole"]
    if hole is not None and not (start.bic < hole.bic and hole.chi2_fit < 2.0 * start.chi2_fit):
        return {}
    return {"hole from region": lambda: fit_hole(search.model, start.shapes[0], search.fit, search.hold,
                                                 search.sigma)}


CAUSE = register(Cause("hole", {2}, "place", ("hole",), jobs,
                       doc="an elliptical hole nobody modelled (at a softer candidate, as the first region)", order=20))
RETRY = register(Cause("hole-from-region", {2}, "reshape", ("hole",), from_region,
                       doc="the hole fitted again from a very soft region's fitted outline", order=10))
