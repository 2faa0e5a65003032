"""A fitted hole's area extrapolated to a fine mesh: Richardson's extrapolation of the area the
model's mesh actually cuts, not of the fitted ellipse's.

A ``tet10`` model cuts a hole as the polygon through the nodes on its curve (the mid-edge nodes
stay straight, :mod:`refine.solid.morph`), and the fit moves that polygon (an affine map of the
ellipse it was meshed at) until the model's hole removes what the data's does. The fitted
ellipse is therefore larger than the hole the model has by the polygon's deficit, and the mesher
puts about as many nodes on a hole at h as at sqrt(2) x h, so that deficit does not fall as h^2
and a refit on a coarser mesh does not see it. The model's stiffness, which the fitted modulus and
the hole's size absorb, does fall as h^2. So the extrapolation is made on the area cut,
``C = fraction(h) x ellipse area``, whose limit h -> 0 is the ellipse's:
``C_fine + (C_fine - C_coarse) / (factor^order - 1)``.

The floor's elements through its thickness are a second discretisation: a refit on a coarser plan
keeps them (the same layers through the floor), so it does not see their error. The cut area
follows ``C0 + a h^2 + b / L^2 + c h^2 / L^2`` over plan sizes h and layers L, with the layers'
error and its coupling to the plan's as large as the plan's own. :func:`with_plan_and_layers`
therefore refits the fitted hole at the corners of that
grid, ``(h, L)``, ``(factor h, L)``, ``(h, L + 1)``, ``(factor h, L + 1)``, and
:func:`extrapolated_area` extrapolates the bilinear form in ``(h^2, 1 / L^2)`` to ``(0, 0)``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

import jaxfem as jf
from jaxfem.mesher import domain
from jaxfem.shapes import curve_nodes


def cut_fraction(local, hole: jf.Ellipse, h: float | None = None) -> float:
    """The share of ``hole``'s area (an ellipse in the cup's frame) that a model built by the
    recipe ``local`` (:class:`~refine.solid.local.Local` or ``Whole``) at element size ``h``
    (length unit; None: ``local.h``) cuts: the polygon through the hole's curve nodes on the
    floor's plan (the plan :func:`jaxfem.wall.rimmed_wall` extrudes), by the shoelace formula."""
    r = local if h is None else local.coarser(h)
    plan = domain(jf.Ellipse(0.0, 0.0, r.shape.r_in, r.shape.r_in), r.floor_h or r.h, holes=(hole,),
                  curve_h=[r.hole_h(hole)])
    x = plan.nodes[curve_nodes(plan, hole)]
    return float(0.5 * abs(x[:, 0] @ np.roll(x[:, 1], -1) - x[:, 1] @ np.roll(x[:, 0], -1)) / hole.area)


def layers_of(local, h: float) -> int:
    """The elements through the floor a recipe ``local`` has at element size ``h``: its ``layers``,
    or the bottom's thickness over ``h`` rounded (:func:`jaxfem.wall.rimmed_wall`'s rule)."""
    return int(local.layers or max(1, int(round(local.shape.bottom / h))))


@dataclass(frozen=True)
class GridRefits:
    """A fitted hole refitted at the corners of the discretisation grid: ``shapes`` per corner
    (``"fine"``: the fit itself at ``(h, layers)``; ``"plan"``: ``(factor h, layers)``;
    ``"layers"``: ``(h, layers + 1)``; ``"both"``: ``(factor h, layers + 1)``), ``None`` for a
    refit that failed."""

    h: float
    layers: int | None
    factor: float
    shapes: dict


def weights(layers: int, factor: float = np.sqrt(2.0), order: float = 2.0, both: bool = True) -> dict:
    """The weights of the corners (:class:`GridRefits`) in the extrapolation to ``(0, 0)`` of a
    quantity bilinear in ``(h^order, 1 / L^2)``; ``both`` False: the plan's Richardson alone."""
    wp = 1.0 / (factor**order - 1.0)  # plan: Q = (1 + wp) Q(h) - wp Q(factor h)
    if not both:
        return {"fine": 1.0 + wp, "plan": -wp}
    y0, y1 = 1.0 / layers**2, 1.0 / (layers + 1) ** 2
    m = y0 / (y0 - y1)  # layers: Q = (1 - m) Q(L) + m Q(L + 1), exact for Q linear in 1 / L^2
    return {"fine": (1 - m) * (1 + wp), "plan": -(1 - m) * wp, "layers": m * (1 + wp), "both": -m * wp}


def refit_grid(fitted, points, hold, sigma: float, factor: float = np.sqrt(2.0)) -> GridRefits | None:
    """The hole of ``fitted`` (a :class:`~refine.diagnosis.fitted.Fitted` of a
    :class:`~refine.solid.local.SolidHole`) refitted from its fitted shapes (and modulus) on the
    three other corners of the grid (:class:`GridRefits`): three more fits, on ``points``, scored on
    ``hold``. None where it has no shapes."""
    from refine.diagnosis.fitted import fit

    hyp = fitted.hypothesis
    if not getattr(fitted, "shapes", ()):
        return None
    h = hyp.h or hyp.local.h
    L = layers_of(hyp.local, h)
    base = hyp.at(fitted.shapes, "tet10")
    corners = {"plan": (factor * h, L), "layers": (h, L + 1), "both": (factor * h, L + 1)}
    shapes = {"fine": tuple(fitted.shapes)}
    for name, (h_c, L_c) in corners.items():
        try:
            g = fit(replace(base, h=h_c, local=replace(base.local, layers=L_c)), points, hold, sigma)
            shapes[name] = tuple(g.shapes)
        except Exception:  # noqa: BLE001 - a mesh that cannot hold the shapes gives no estimate there
            shapes[name] = None
    return GridRefits(h, L, factor, shapes)


def extrapolate(grid: GridRefits, order: float = 2.0) -> tuple[np.ndarray, np.ndarray] | None:
    """The shapes' quantities (:data:`refine.diagnosis.uncertainty.QUANTITIES`, ``(shapes, 7)``)
    extrapolated to ``(0, 0)`` from the grid's corners, and the plan's Richardson alone at the
    fit's layers; orientations taken within a quarter turn of the fit's. None without the plan's
    refit; the plan's extrapolation twice where a refit with more layers failed."""
    from refine.diagnosis.uncertainty import shape_quantities

    if grid.shapes.get("plan") is None:
        return None
    q = {k: shape_quantities(v) for k, v in grid.shapes.items() if v is not None}
    for k in q:  # an orientation is defined modulo pi
        q[k][:, 4] = q["fine"][:, 4] + np.angle(np.exp(2j * (q[k][:, 4] - q["fine"][:, 4]))) / 2
    return _combined(q, grid, order)


def _combined(values: dict, grid: GridRefits, order: float) -> tuple:
    """``values`` per corner (``"fine"`` and ``"plan"`` at least) extrapolated to ``(0, 0)`` by
    :func:`weights`, and the plan's Richardson alone; the latter twice where a corner with more
    layers is missing."""
    plan = sum(w * values[k] for k, w in weights(grid.layers, grid.factor, order, both=False).items())
    if "layers" not in values or "both" not in values:
        return plan, plan
    return sum(w * values[k] for k, w in weights(grid.layers, grid.factor, order).items()), plan


def with_plan_and_layers(fitted, points, hold, sigma: float, factor: float = np.sqrt(2.0)):
    """``fitted`` with its discretisation error from the grid's refits (:func:`refit_grid`):
    ``q_disc_signed`` the fit's error with its sign (the fit less the extrapolation to ``(0, 0)``),
    ``q_disc`` its size, ``q_disc_parts`` ``{"plan": the plan's Richardson alone, "layers": the
    rest}`` (sizes), ``q_disc_refits`` the grid. Unchanged where the plan's refit failed."""
    grid = refit_grid(fitted, points, hold, sigma, factor)
    out = None if grid is None else extrapolate(grid)
    if out is None:
        return fitted
    from refine.diagnosis.uncertainty import shape_quantities

    limit, plan = out
    fine = shape_quantities(fitted.shapes)
    signed = fine - limit
    return replace(fitted, q_disc=np.abs(signed), q_disc_signed=signed, q_disc_refits=grid,
                   q_disc_parts={"plan": np.abs(fine - plan), "layers": np.abs(plan - limit)})


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
    fit's shape.

    Where ``fitted`` carries the grid's refits (``q_disc_refits``, :func:`with_plan_and_layers`),
    the cut areas of its four corners are extrapolated to ``(0, 0)`` (:func:`weights`). The parts
    also hold ``cut_layers``, ``cut_both``, ``layers`` (the fit's; None for a signed change
    alone) and ``area_plan_only`` (the plan's Richardson alone, the area where no refit with more
    layers is known)."""
    grid = getattr(fitted, "q_disc_refits", None)
    if grid is not None and grid.shapes.get("plan") is not None:
        return _grid_area(fitted, grid, order)
    signed = getattr(fitted, "q_disc_signed", None)
    if signed is None or not np.isfinite(signed[0, 5]):
        return None
    # the coarse refit known by its signed change alone: its ellipse, the fit's scaled to its area
    hyp, s = fitted.hypothesis, fitted.shapes[0]
    fine_area = float(np.pi * s.axes[0] * s.axes[1])
    coarse_area = fine_area + float(signed[0, 5]) * (factor**order - 1.0)  # signed: (coarse - fine) / (r^p - 1)
    k = np.sqrt(coarse_area / fine_area)
    coarse = replace(s, axes=(s.axes[0] * k, s.axes[1] * k))
    grid = GridRefits(hyp.h or hyp.local.h, None, factor, {"fine": (s,), "plan": (coarse,)})
    return _grid_area(fitted, grid, order)


def _grid_area(fitted, grid: GridRefits, order: float) -> dict:
    """:func:`extrapolated_area` from the grid's corners (each model's polygon share is that of
    the ellipse its mesh was built at: the fit's last remesh for the fit, the fit's shape for the
    refits; the layers do not change the plan)."""
    hyp, s = fitted.hypothesis, fitted.shapes[0]
    h, at = grid.h, jf.Ellipse(*s.centre, *s.axes, s.angle)
    frac = {"fine": cut_fraction(hyp.local, hyp.hole, h), "plan": cut_fraction(hyp.local, at, grid.factor * h)}
    if grid.shapes.get("layers") is not None:  # the layers do not change the plan: the fine one, at the fit's shape
        frac["layers"] = cut_fraction(hyp.local, at, h)
    frac["both"] = frac["plan"]
    cut = {k: frac[k] * float(np.pi * v[0].axes[0] * v[0].axes[1]) for k, v in grid.shapes.items() if v is not None}
    area, plan_only = _combined(cut, grid, order)
    return {"area": float(area), "cut_fine": float(cut["fine"]), "cut_coarse": float(cut["plan"]),
            "fraction_fine": frac["fine"], "fraction_coarse": frac["plan"], "layers": grid.layers,
            "cut_layers": float(cut["layers"]) if "layers" in cut else None,
            "cut_both": float(cut["both"]) if "both" in cut else None, "area_plan_only": float(plan_only)}
