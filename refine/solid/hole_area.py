"""A fitted hole's area extrapolated to a fine mesh: Richardson's extrapolation of the area the
model's mesh actually cuts, not of the fitted ellipse's.

A ``tet10`` model cuts a hole as the polygon through the nodes on its curve (the mid-edge nodes
stay straight, :mod:`refine.solid.morph`), and the fit moves that polygon (an affine map of the
ellipse it was meshed at) until the model's hole removes what the data's does. The fitted
ellipse is therefore larger than the hole the model has by the polygon's deficit (at h 1.2 the
benchmark's holes keep 0.959-0.973 of their ellipses), and the mesher puts about as many nodes on
a hole at h 1.2 as at sqrt(2) x 1.2 (13-16), so that deficit does not fall as h^2 and a refit on
a coarser mesh does not see it. The model's stiffness, which the fitted modulus and the hole's
size absorb, does fall as h^2 (the modulus refitted sqrt(2) coarser extrapolates to 0.998-1.000 of
the data's on the benchmark's seeds). So the extrapolation is made on the area cut,
``C = fraction(h) x ellipse area``, whose limit h -> 0 is the ellipse's:
``C_fine + (C_fine - C_coarse) / (factor^order - 1)`` (benchmarks/README.md, diagnose3d, session 24).
"""

from __future__ import annotations

import numpy as np

import jaxfem as jf
from jaxfem.mesher import domain
from jaxfem.shapes import curve_nodes


def cut_fraction(local, hole: jf.Ellipse, h: float | None = None) -> float:
    """The share of ``hole``'s area (an ellipse in the cup's frame) that a model built by the
    recipe ``local`` (:class:`~refine.solid.local.Local` or ``Whole``) at element size ``h``
    (length unit; None: ``local.h``) cuts: the polygon through the hole's curve nodes on the
    floor's plan (the plan :func:`jaxfem.cup.cup_holder` extrudes), by the shoelace formula."""
    r = local if h is None else local.coarser(h)
    plan = domain(jf.Ellipse(0.0, 0.0, r.shape.r_in, r.shape.r_in), r.floor_h or r.h, holes=(hole,),
                  curve_h=[r.hole_h(hole)])
    x = plan.nodes[curve_nodes(plan, hole)]
    return float(0.5 * abs(x[:, 0] @ np.roll(x[:, 1], -1) - x[:, 1] @ np.roll(x[:, 0], -1)) / hole.area)


def extrapolated_area(fitted, factor: float = np.sqrt(2.0), order: float = 2.0) -> dict | None:
    """Richardson's extrapolation of the area cut by the hole of ``fitted`` (a
    :class:`~refine.diagnosis.fitted.Fitted` of a :class:`~refine.solid.local.SolidHole`, with the
    signed change of its refit ``factor`` times coarser, ``q_disc_signed``:
    :func:`refine.diagnosis.uncertainty.with_discretisation`), for errors of ``order``.

    Returns ``{"area", "cut_fine", "cut_coarse", "fraction_fine", "fraction_coarse"}`` (areas in
    length squared): the extrapolated area and the areas the fine and the coarse models cut with
    their polygons' shares of the fitted ellipses; None without the signed change. Each model's
    share is that of the ellipse its mesh was built at (the fit moves the polygon by an affine
    map, which keeps the share): the fine fit's last remesh, and for the coarse refit the fine
    fit's shape."""
    signed = getattr(fitted, "q_disc_signed", None)
    if signed is None or not np.isfinite(signed[0, 5]):
        return None
    hyp, s = fitted.hypothesis, fitted.shapes[0]
    h = hyp.h or hyp.local.h
    fine_area = float(np.pi * s.axes[0] * s.axes[1])
    coarse_area = fine_area + float(signed[0, 5]) * (factor**order - 1.0)  # signed: (coarse - fine) / (r^p - 1)
    f_fine = cut_fraction(hyp.local, hyp.hole, h)
    f_coarse = cut_fraction(hyp.local, jf.Ellipse(*s.centre, *s.axes, s.angle), factor * h)
    c_fine, c_coarse = f_fine * fine_area, f_coarse * coarse_area
    return {"area": float(c_fine + (c_fine - c_coarse) / (factor**order - 1.0)), "cut_fine": float(c_fine),
            "cut_coarse": float(c_coarse), "fraction_fine": f_fine, "fraction_coarse": f_coarse}
