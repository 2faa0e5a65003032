"""A region of other stiffness as a rectangle (2D), started from a fitted one-region ellipse (the
paper's scar: fitted as an ellipse, a stiff rectangle comes out larger and too soft, its corners'
load paths missing). A ``"reshape"`` cause: jobs ``"rectangle"`` and ``"rectangle turned"``
(:func:`refine.diagnosis.regions.fit_rectangle`, turned 0 and pi/4 from the ellipse, each
remeshed at its fit) beside ``"ellipse remeshed"`` (:func:`refine.diagnosis.regions.refit_ellipse`:
the ellipse remeshed at its fit, on equal terms; it supersedes the ellipse as first fitted).
Its fits name ``"stiffer-region"`` or ``"softer-region"``; a failed fit's row names ``"region"``."""

from __future__ import annotations

import numpy as np

from refine.causes.registry import Cause, register
from refine.diagnosis.config import DiagnoseConfig
from refine.diagnosis.fitted import Fitted
from refine.diagnosis.regions import fit_rectangle, refit_ellipse


def rectangles_wanted(region: Fitted, model, cfg: DiagnoseConfig, explained: bool = False) -> bool:
    """Whether to fit ``region`` (one fitted ellipse) as a rectangle too: as
    ``cfg.try_rectangles`` says, or, when it is None, where the ellipse leaves a misfit the noise
    does not explain (``explained`` False) and its smaller semi-axis spans
    ``cfg.rectangle_spacings`` grid spacings (fewer tracked points along a side cannot tell a
    corner from a curve)."""
    if cfg.try_rectangles is not None:
        return bool(cfg.try_rectangles)
    return not explained and min(region.shapes[0].axes) >= cfg.rectangle_spacings * model.spacing


def jobs(search, start) -> dict:
    """The rectangles from ``start``, a one-region fit at the first candidate
    (:class:`refine.diagnosis.search.AtCandidate`) that leads the candidate's fits so far, where
    :func:`rectangles_wanted`; nothing otherwise (never for two regions)."""
    from refine.diagnosis.search import Superseding

    if (search.used or start.cause not in ("stiffer-region", "softer-region")
            or not rectangles_wanted(start, search.model, search.cfg, search.explains(start))
            or not search.leads(start)):
        return {}
    m, fit, hold, sigma = search.model, search.fit, search.hold, search.sigma
    return {"rectangle": lambda: fit_rectangle(m, start, 0.0, fit, hold, sigma),
            "rectangle turned": lambda: fit_rectangle(m, start, np.pi / 4, fit, hold, sigma),
            "ellipse remeshed": Superseding(lambda: refit_ellipse(start, fit, hold), start)}


CAUSE = register(Cause("rectangle", {2}, "reshape", ("region", "stiffer-region", "softer-region"), jobs,
                       doc="a fitted region as a rectangle (turned 0 and pi/4), beside the ellipse remeshed",
                       order=20))
