"""Regions of other stiffness: ellipses or rectangles whose centre, axes or sides, orientation
and moduli are fitted by exact gradients, on meshes that follow them."""

from __future__ import annotations

import numpy as np

import jaxfem as jf

from refine.diagnosis.fitted import Fitted, NotApplicable, _fit, _moved
from refine.model.measured import MeasuredModel, domain_mesh
from refine.model.objective import Compiled
from refine.model.parametrize import Combined, RegionModuli, ShapeGeometry, make_shape


def _clamp_shape(shape, ex, spacing):
    """Keep a candidate ellipse inside the domain, at least about one grid spacing across."""
    dom = ex.domain
    a, b = max(shape[2], 0.6 * spacing), max(shape[3], 0.6 * spacing)
    m = 0.5 * spacing
    cx = float(np.clip(shape[0], dom.xmin + a + m, dom.xmax - a - m)) if dom.xmax - dom.xmin > 2 * (a + m) else shape[0]
    cy = float(np.clip(shape[1], dom.ymin + b + m, dom.ymax - b - m)) if dom.ymax - dom.ymin > 2 * (b + m) else shape[1]
    return cx, cy, a, b, shape[4]


def _mesh_size(base: MeasuredModel, ells) -> float:
    """Element size of a hypothesis' mesh: the base model's (half the grid spacing), but fine
    enough to resolve each shape (its smaller semi-axis over 2.5), and not below a quarter of
    the spacing. Linear triangles too coarse around a hole or a region are too stiff there, and
    the fit makes up for it with a larger hole or a softer region (+21 % hole area at 5 mm
    elements, +12 % at 2.5 mm, on one 10 mm-grid bundle)."""
    smallest = min(min(e.params[2], e.params[3]) for e in ells)
    return float(min(base.h, max(smallest / 2.5, 0.25 * base.spacing)))


def _shrunk(shape, factor: float):
    """The same ellipse or rectangle, its axes or sides times ``factor`` about its centre."""
    p = shape.params * [1, 1, factor, factor, 1]
    return make_shape("rectangle" if isinstance(shape, jf.Rect) else "ellipse", p)


def _disjoint(shapes, gap):
    """Shrink shapes that overlap (or nearly touch) until they are ``gap`` apart."""
    shapes = list(shapes)
    for _ in range(20):
        clash = False
        for i in range(len(shapes)):
            for j in range(i + 1, len(shapes)):
                a, b = shapes[i], shapes[j]
                pa = np.concatenate([p for p, _ in a._pieces(gap / 4)])
                if b.contains(pa).any() or np.min(np.linalg.norm(pa - b.to_curve(pa), axis=1)) < gap:
                    clash = True
                    shapes[i], shapes[j] = _shrunk(a, 0.85), _shrunk(b, 0.85)
        if not clash:
            return shapes
    raise ValueError("candidate regions overlap")


MIN_AXIS = 0.25
"""Smallest semi-axis of a fitted region, in grid spacings: a thinner one is not resolved by the
tracked points (a fit once flattened a spurious second region to 1.7 x 19.6 mm on an 8 mm grid)."""


RECTANGLE_SIDE = np.sqrt(3.0) / 2.0
"""Half side of the rectangle with the second moments of an ellipse of semi-axis 1 (a uniform
ellipse's variance along an axis is a^2 / 4, a rectangle's s^2 / 3)."""


def region_model(base: MeasuredModel, regions, h: float, element: str = "tri3", geometry: bool = True):
    """The model of :func:`fit_regions` for shapes ``regions`` (``jaxfem.Ellipse``/``Rect``): a
    mesh of element size ``h`` that follows them, and its parametrisation: the log moduli of the
    regions, then (with ``geometry``) the changes of their shapes (zero: the shapes given)."""
    ex = base.experiment
    mesh = domain_mesh(ex, h, element, inclusions=regions)
    model = MeasuredModel(ex, base.obs, mesh=mesh, h=h)
    masks = np.stack([(mesh.regions == k + 1).astype(float) for k in range(len(regions))])
    parts = [RegionModuli(masks, ex.E, names=tuple(f"region{k + 1}" for k in range(len(regions))))]
    if geometry:
        kinds = tuple("rectangle" if isinstance(r, jf.Rect) else "ellipse" for r in regions)
        parts.append(ShapeGeometry(jf.morph(mesh, regions), np.stack([e.params for e in regions]), scale=base.spacing,
                                   rotate=True, mesh=mesh, min_axis=MIN_AXIS * base.spacing, kinds=kinds))
    return model, Combined(tuple(parts))


def fit_regions(base: MeasuredModel, shapes, signs, fit_mask, hold_mask, sigma, geometry: bool = True,
                h: float | None = None, ratios=None, element: str = "tri3", kinds=None) -> Fitted:
    """Regions of other stiffness: shapes ``[(cx, cy, a, b, angle)]`` of ``kinds`` (``"ellipse"``,
    the default, or ``"rectangle"``: then ``a, b`` are half sides) with fitted log moduli (start:
    ``ratios``, default x3 for stiffer, /3 for softer) and, with ``geometry``, fitted centres,
    axes or sides, and orientations.

    A rectangle is worth its own hypothesis: fitted as an ellipse, a stiff rectangle (the paper's
    scar) comes out larger and too soft, its corners' load paths missing (ratios 12-30 % low on
    random rectangles of ratio 10, at 2-7 of their standard errors)."""
    ex = base.experiment
    kinds = tuple(kinds or ("ellipse",) * len(shapes))
    regions = _disjoint([make_shape(k, _clamp_shape(s, ex, base.spacing)) for k, s in zip(kinds, shapes)],
                        base.spacing)
    model, param = region_model(base, regions, h or _mesh_size(base, regions), element, geometry)
    parts = param.parts
    z0 = np.zeros(param.size)
    z0[: len(regions)] = np.log(3.0) * np.asarray(signs, float) if ratios is None else np.log(ratios)
    n = len(regions)

    def shapes_from(z):
        ratios = np.exp(z[:n])
        geo = np.asarray(parts[1].shape_params(z[n:])) if geometry else np.stack([e.params for e in regions])
        return [(kinds[k], *geo[k, :4], geo[k, 4], float(ratios[k])) for k in range(n)]

    out = _fit("regions", Compiled(model, param), fit_mask, hold_mask, sigma, z0=z0, shapes_from=shapes_from,
               law=ex.law)
    causes = {"stiffer-region" if s[6] > 1 else "softer-region" for s in out.shapes}
    out.cause = causes.pop() if len(causes) == 1 and n == 1 else "regions"
    if geometry:
        out.remesh = lambda fitted, pts, hold, el: fit_regions(base, [f[1:6] for f in fitted], signs, pts, hold,
                                                               sigma, h=h, ratios=[f[6] for f in fitted], element=el,
                                                               kinds=[f[0] for f in fitted])
    return out


def remeshed(f: Fitted, fit_mask, hold_mask, max_remesh: int = 1, start=None) -> Fitted:
    """``f`` remeshed at its fitted shapes and refitted (linear triangles, the same points), again
    while the shapes move by more than a fifth of an element from ``start`` (default: where
    they are now); the best fit is returned (``f`` itself if it did not move that far)."""
    start = f.shapes if start is None else start
    for _ in range(max_remesh):
        if f.remesh is None or max(_moved(a, b) for a, b in zip(start, f.shapes)) < 0.2 * f.model.h:
            break
        start = f.shapes
        try:
            g = f.remesh(f.shapes, fit_mask, hold_mask, "tri3")
        except Exception:  # noqa: BLE001 - a remesh that no longer solves: keep what there is
            break
        if not np.isfinite(g.chi2_fit) or g.chi2_fit >= f.chi2_fit:
            break
        f = g
    return f


def fit_rectangle(base: MeasuredModel, region: Fitted, turn: float, fit_mask, hold_mask, sigma,
                  max_remesh: int = 1) -> Fitted:
    """A region fitted as a rectangle, started from a fitted one-region ellipse ``region``: the
    rectangle of the same centre and second moments, turned ``turn`` radians from the ellipse
    (a near-circular ellipse says nothing of a square's orientation: try 0 and a quarter turn
    of it, pi / 4), its ratio as fitted. Remeshed at the fitted rectangle and refitted while it
    moves by more than a fifth of an element (:func:`remeshed`): a morph that turns a rectangle
    shears the cells at its corners, and from a start 17 degrees off a rectangle of ratio 10
    stopped 4 degrees off (chi2 1413, against 999 at the true rectangle; no descent on that
    mesh). Compare it with the ellipse remeshed the same way: a remeshed fit has the advantage
    of a fresh mesh (on 10 mm grids rectangles beat the first ellipse fits of true ellipses)."""
    kind, cx, cy, a, b, ang, ratio = region.shapes[0]
    if kind != "ellipse" or len(region.shapes) != 1:
        raise NotApplicable("a rectangle is started from a single fitted ellipse")
    start = ("rectangle", cx, cy, RECTANGLE_SIDE * a, RECTANGLE_SIDE * b, ang + turn, ratio)
    f = fit_regions(base, [start[1:6]], [1 if ratio > 1 else -1], fit_mask, hold_mask, sigma, ratios=[ratio],
                    kinds=["rectangle"])
    return remeshed(f, fit_mask, hold_mask, max_remesh, start=[start])


def refit_ellipse(region: Fitted, fit_mask, hold_mask, max_remesh: int = 1) -> Fitted:
    """The fitted ellipse remeshed at its fit and refitted (:func:`remeshed`, from the shapes its
    mesh was built at), to be compared with :func:`fit_rectangle` on equal terms."""
    geo = region.compiled.param.parts[-1] if isinstance(region.compiled.param, Combined) else region.compiled.param
    built = [(s[0], *np.asarray(geo.params0)[k], s[6]) for k, s in enumerate(region.shapes)]
    return remeshed(region, fit_mask, hold_mask, max_remesh, start=built)
