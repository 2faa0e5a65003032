"""Regions of other stiffness: ellipses or rectangles whose centre, axes or sides, orientation
and moduli are fitted by exact gradients, on meshes that follow them."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import jaxfem as jf

from refine.diagnosis.fitted import Fitted, NotApplicable, fit
from refine.diagnosis.restarts import RESTARTS, best_of_restarts
from refine.diagnosis.shapes import RegionShape
from refine.exceptions import RefineError
from refine.model.measured import MeasuredModel, domain_mesh
from refine.model.objective import Compiled
from refine.model.parametrize import Combined, RegionModuli, ShapeGeometry, bounded_exp, make_shape


class OverlappingRegions(RefineError, ValueError):
    """Candidate regions that still overlap after shrinking them (the hypothesis is not fitted)."""


def _mesh_size(base: MeasuredModel, ells) -> float:
    """Element size of a hypothesis' mesh: the base model's (half the grid spacing), but fine
    enough to resolve each shape (its smaller semi-axis over 2.5), and not below a quarter of
    the spacing. Linear triangles too coarse around a hole or a region are too stiff there, and
    the fit makes up for it with a larger hole or a softer region."""
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
    raise OverlappingRegions("candidate regions overlap")


MIN_AXIS = 0.25
"""Smallest semi-axis of a fitted region, in grid spacings: a thinner one is not resolved by the
tracked points."""


RECTANGLE_SIDE = np.sqrt(3.0) / 2.0
"""Half side of the rectangle with the second moments of an ellipse of semi-axis 1 (a uniform
ellipse's variance along an axis is a^2 / 4, a rectangle's s^2 / 3)."""


def region_model(base: MeasuredModel, regions, h: float, element: str = "tri3", geometry: bool = True):
    """The model of :func:`fit_regions` for shapes ``regions`` (``jaxfem.Ellipse``/``Rect``): a
    mesh of element size ``h`` that follows them, and its parametrisation: the log moduli of the
    regions, then (with ``geometry``) the changes of their shapes (zero: the shapes given)."""
    ex = base.experiment
    mesh = domain_mesh(ex, h, element, inclusions=regions)
    model = MeasuredModel(ex, base.obs, mesh=mesh, h=h, linear_solver=base.linear_solver)
    masks = np.stack([(mesh.regions == k + 1).astype(float) for k in range(len(regions))])
    parts = [RegionModuli(masks, ex.E, names=tuple(f"region{k + 1}" for k in range(len(regions))))]
    if geometry:
        kinds = tuple("rectangle" if isinstance(r, jf.Rect) else "ellipse" for r in regions)
        parts.append(ShapeGeometry(jf.morph(mesh, regions), np.stack([e.params for e in regions]), scale=base.spacing,
                                   rotate=True, mesh=mesh, min_axis=MIN_AXIS * base.spacing, kinds=kinds))
    return model, Combined(tuple(parts))


@dataclass(frozen=True, eq=False)
class Regions:
    """The hypothesis of regions of other stiffness in ``base``: the ``jaxfem`` shapes its mesh
    follows (kept inside the domain and apart), the signs of their starting log moduli (x3 for
    stiffer, /3 for softer) or their starting ``ratios``, whether their geometry is fitted, and
    the mesh's element size ``h`` (None: :func:`_mesh_size`) and ``element``."""

    base: MeasuredModel
    regions: tuple
    signs: tuple
    ratios: tuple | None = None
    geometry: bool = True
    h: float | None = None
    element: str = "tri3"

    @property
    def law(self) -> str:
        return self.base.experiment.law

    @property
    def remeshable(self) -> bool:
        return self.geometry

    def build(self) -> tuple[Compiled, np.ndarray]:
        """The compiled model (:func:`region_model`) and its start: the log ratios, then zero
        changes of the shapes."""
        model, param = region_model(self.base, self.regions, self.h or _mesh_size(self.base, self.regions),
                                    self.element, self.geometry)
        z0 = np.zeros(param.size)
        n = len(self.regions)
        z0[:n] = np.log(3.0) * np.asarray(self.signs, float) if self.ratios is None else np.log(self.ratios)
        return Compiled(model, param), z0

    def shapes_at(self, compiled: Compiled, z) -> tuple[RegionShape, ...]:
        n = len(self.regions)
        ratios = bounded_exp(z[:n])  # (a drawn z may lie far beyond any fit: no overflow)
        if not self.geometry:
            return tuple(RegionShape.of(e, float(r)) for e, r in zip(self.regions, ratios))
        geo = np.asarray(compiled.param.parts[1].shape_params(z[n:]))
        return tuple(RegionShape((g[0], g[1]), (g[2], g[3]), g[4], RegionShape.of(e).kind, float(r))
                     for e, g, r in zip(self.regions, geo, ratios))

    def cause_of(self, shapes) -> str:
        causes = {s.cause for s in shapes}
        return causes.pop() if len(causes) == 1 and len(shapes) == 1 else "regions"

    def at(self, shapes, element: str) -> Regions:
        return regions_hypothesis(self.base, shapes, self.signs, h=self.h, element=element)


def regions_hypothesis(base: MeasuredModel, shapes, signs, geometry: bool = True, h: float | None = None,
                       element: str = "tri3") -> Regions:
    """The :class:`Regions` hypothesis started at ``shapes`` (:class:`RegionShape`: ellipses or
    rectangles, their ``ratio`` the starting relative elasticity; None in all: x3 or /3 by
    ``signs``), kept inside the domain, about a grid spacing across at least, and apart."""
    regions = _disjoint([s.clamped(base.experiment.domain, base.spacing).geometry() for s in shapes], base.spacing)
    ratios = None if all(s.ratio is None for s in shapes) else tuple(s.ratio for s in shapes)
    return Regions(base, tuple(regions), tuple(signs), ratios, geometry, h, element)


def fit_regions(base: MeasuredModel, shapes, signs, fit_mask, hold_mask, sigma, geometry: bool = True,
                h: float | None = None, element: str = "tri3", restarts=RESTARTS) -> Fitted:
    """Regions of other stiffness (:func:`regions_hypothesis`) with fitted log moduli and, with
    ``geometry``, fitted centres, axes or sides, and orientations; refitted from ``restarts``
    at the fitted centres (:func:`~refine.diagnosis.restarts.best_of_restarts`: a fit started
    off the centre can stop in a local minimum of the trade between outline, size and ratio),
    the lowest misfit kept.

    A rectangle is worth its own hypothesis: fitted as an ellipse, a stiff rectangle (the paper's
    scar) comes out larger and too soft, its corners' load paths missing."""
    f = fit(regions_hypothesis(base, shapes, signs, geometry, h, element), fit_mask, hold_mask, sigma)
    return best_of_restarts(f, shapes, fit_mask, hold_mask, restarts if geometry else ())


def remeshed(f: Fitted, fit_mask, hold_mask, max_remesh: int = 1, start=None) -> Fitted:
    """``f`` remeshed at its fitted shapes and refitted (linear triangles, the same points), again
    while the shapes move by more than a fifth of an element from ``start`` (default: where
    they are now); the best fit is returned (``f`` itself if it did not move that far)."""
    start = f.shapes if start is None else start
    for _ in range(max_remesh):
        if not f.hypothesis.remeshable or max(a.moved(b) for a, b in zip(start, f.shapes)) < 0.2 * f.model.h:
            break
        start = f.shapes
        try:
            g = fit(f.hypothesis.at(f.shapes, "tri3"), fit_mask, hold_mask, f.sigma)
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
    shears the cells at its corners and stops short. Compare it with the ellipse remeshed the
    same way (:func:`refit_ellipse`): a remeshed fit has the advantage of a fresh mesh."""
    if len(region.shapes) != 1 or region.shapes[0].kind != "ellipse":
        raise NotApplicable("a rectangle is started from a single fitted ellipse")
    ellipse = region.shapes[0]
    start = RegionShape(ellipse.centre, (RECTANGLE_SIDE * ellipse.axes[0], RECTANGLE_SIDE * ellipse.axes[1]),
                        ellipse.angle + turn, "rectangle", ellipse.ratio)
    f = fit_regions(base, [start], [1 if ellipse.ratio > 1 else -1], fit_mask, hold_mask, sigma, restarts=())
    return remeshed(f, fit_mask, hold_mask, max_remesh, start=[start])


def refit_ellipse(region: Fitted, fit_mask, hold_mask, max_remesh: int = 1) -> Fitted:
    """The fitted ellipse remeshed at its fit and refitted (:func:`remeshed`, from the shapes its
    mesh was built at), to be compared with :func:`fit_rectangle` on equal terms."""
    built = [RegionShape.of(e, s.ratio) for e, s in zip(region.hypothesis.regions, region.shapes)]
    return remeshed(region, fit_mask, hold_mask, max_remesh, start=built)
