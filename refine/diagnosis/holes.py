"""A hole: an ellipse removed from the domain, its centre, axes and orientation fitted."""

from __future__ import annotations

import numpy as np

import jaxfem as jf

from refine.diagnosis.fitted import Fitted, NotApplicable, _fit
from refine.diagnosis.regions import _clamp_shape, _mesh_size
from refine.model.measured import MeasuredModel, domain_mesh
from refine.model.objective import Compiled
from refine.model.parametrize import ShapeGeometry


HOLE_MIN_SHRINK = 0.25
"""A hole candidate is tried only if an ellipse of at least this share of its axes, about its
centre, is free of tracked points (a true hole has none inside)."""


def fit_hole(base: MeasuredModel, shape, fit_mask, hold_mask, sigma, h: float | None = None,
             element: str = "tri3") -> Fitted:
    """A hole: an ellipse removed from the domain, centre, axes and orientation fitted. The
    starting ellipse is shrunk until no tracked point lies inside it (material was seen there); a
    candidate that has to shrink below ``HOLE_MIN_SHRINK`` of its size has tracked material near
    its middle and is no hole (:class:`NotApplicable`, not fitted: such a start is a pinhole that
    needs a very fine mesh, and its fit cost minutes to lose)."""
    ex, obs = base.experiment, base.obs
    cx, cy, a, b, ang = _clamp_shape(shape, ex, base.spacing)
    pts = obs.reference
    size = max(a, b)
    for _ in range(30):
        e = jf.Ellipse(cx, cy, a, b, ang)
        if not e.contains(pts).any() and np.min(np.linalg.norm(pts - e.to_curve(pts), axis=1)) > 0.2 * base.spacing:
            break
        a, b = 0.9 * a, 0.9 * b
    else:
        a = b = 0.0  # no start free of tracked points
    if max(a, b) < HOLE_MIN_SHRINK * size:
        near = pts[np.argmin(np.linalg.norm(pts - [cx, cy], axis=1))]
        raise NotApplicable(f"no hole at ({cx:.1f}, {cy:.1f}): the tracked point at ({near[0]:.1f}, {near[1]:.1f}) "
                         "lies near its middle (material was seen there)")
    hole = jf.Ellipse(cx, cy, a, b, ang)
    size = h or _mesh_size(base, [hole])
    mesh = domain_mesh(ex, size, element, holes=[hole])
    model = MeasuredModel(ex, obs, mesh=mesh, h=size)
    param = ShapeGeometry(jf.morph(mesh, [hole]), hole.params[None], scale=0.5 * base.spacing, rotate=True,
                          mesh=mesh, outside=pts, min_axis=0.1 * base.spacing)

    def shapes_from(z):
        g = np.asarray(param.shape_params(z))[0]
        return [("hole", *g[:4], g[4], 0.0)]

    out = _fit("hole", Compiled(model, param), fit_mask, hold_mask, sigma, shapes_from=shapes_from, law=ex.law)
    out.remesh = lambda fitted, pts, hold, el: fit_hole(base, fitted[0][1:6], pts, hold, sigma, h=h, element=el)
    return out
