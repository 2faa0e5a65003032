"""Where the global model's hole fit starts: along the painted grid's bracket of the hole's edge
(:mod:`refine.solid.edge`), the ellipse between the tracked and the missing crossings moved inward
by a few fractions of a grid step, each tried in the global model by one solve (its modulus scaled
to fit, the model's only other unknown) and the best taken.

Why: the edge lies anywhere between the last tracked crossing and a missing one up to the slack
beyond the hole (a tracker loses crossings within about 0.7 pitch of a hole), and a fit on a
morph travels only so far before its remeshes run out: started at the ellipse between the two
sets, a fit can end far larger than the hole the data fix.
"""

from __future__ import annotations

import numpy as np

import jaxfem as jf

from refine.diagnosis.fitted import NotApplicable
from refine.diagnosis.shapes import Hole
from refine.measures import Residuals
from refine.solid.edge import EdgeEvidence
from refine.solid.local import Local

OFFSETS = (0.75, 0.4, 0.05)
"""How far (grid steps) the tried starts' outlines lie inside the ellipse between the tracked and
the missing crossings."""


def bracket_starts(local: Local, edge: EdgeEvidence, offsets=OFFSETS) -> list[jf.Ellipse]:
    """Starts along the bracket (see the module): the ellipse between the sets with its axes
    shortened by each of ``offsets`` steps (at least a third of a step left), kept inside the floor
    and off the tracked points (:meth:`Local.hole_from`), those that still reach every missing
    crossing within the slack."""
    cx, cy, a, b, angle = map(float, edge.ellipse)
    out = []
    for k in offsets:
        d = k * edge.step
        shape = Hole((cx, cy), (max(a - d, edge.step / 3), max(b - d, edge.step / 3)), angle)
        try:
            e = local.hole_from(shape)
        except NotApplicable:
            continue
        if edge.missing_outside(e.params) <= edge.slack:
            out.append(e)
    return out


def best_start(whole: Local, starts: list[jf.Ellipse], points, sigma: float,
               log=print) -> tuple[jf.Ellipse, float]:
    """The start among ``starts`` whose global model (``whole``'s, the hole cut) fits the
    ``points`` (mask) best at the noise ``sigma`` after one solve, its modulus scaled to fit
    (displacements under a measured force scale as 1/E: the prediction times a factor in
    [0.5, 2], least squares), and that modulus (the experiment's unit): the hole fit starts there."""
    at = Residuals.at(whole.obs.displacements, points, sigma)
    best, chi2_best, E = starts[0], np.inf, float(whole.experiment.E)
    for e in starts:
        model, _ = whole.model(e)
        pred = np.asarray(model.predict(model.params()))
        r0 = at(pred)
        v = at(2 * pred) - r0  # the prediction's own weighted values
        s = float(np.clip(1 - (r0 @ v) / max(v @ v, 1e-300), 0.5, 2.0))
        r = r0 + (s - 1) * v
        chi2 = float(r @ r)
        log(f"  global start: axes ({e.rx:.2f}, {e.ry:.2f}), area {np.pi * e.rx * e.ry:.2f}, modulus x {1 / s:.3f}: "
            f"chi2 {chi2:.0f}")
        if chi2 < chi2_best:
            best, chi2_best, E = e, chi2, float(whole.experiment.E) / s
    return best, E
