"""A hole: an ellipse removed from the domain, its centre, axes and orientation fitted."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

import jaxfem as jf

from refine.diagnosis.fitted import Fitted, NotApplicable, fit
from refine.diagnosis.regions import _mesh_size
from refine.diagnosis.restarts import best_of_restarts
from refine.diagnosis.shapes import Hole
from refine.diagnosis.subsets import hole_from_subsets, seen_material, subset_distance
from refine.model.measured import MeasuredModel, domain_mesh
from refine.model.objective import Compiled
from refine.model.parametrize import ShapeGeometry


HOLE_MIN_SHRINK = 0.25
"""A hole candidate is tried only if an ellipse of at least this share of its axes, about its
centre, is free of tracked points (a true hole has none inside)."""


class HoleShape:
    """What a hole hypothesis (on a sheet, or through a solid's wall) reads off its fit: the hole
    from the geometry unknowns (centre, axes, angle), and its cause."""

    def shapes_at(self, compiled: Compiled, z) -> tuple[Hole]:
        g = np.asarray(compiled.param.shape_params(z))[0]
        return (Hole((g[0], g[1]), (g[2], g[3]), g[4]),)

    def cause_of(self, shapes) -> str:
        return "hole"


@dataclass(frozen=True, eq=False)
class HoleHypothesis(HoleShape):
    """The hypothesis of a hole in ``base`` at ``hole`` (a ``jaxfem.Ellipse`` free of tracked
    points), meshed at element size ``h`` (None: :func:`_mesh_size`) with ``element``; with
    ``subsets`` (and the bundle's subset known) the hole also keeps out of every tracked point's
    subset (:func:`_seen`)."""

    base: MeasuredModel
    hole: jf.Ellipse
    h: float | None = None
    element: str = "tri3"
    subsets: bool = True
    remeshable = True

    @property
    def law(self) -> str:
        return self.base.experiment.law

    def build(self) -> tuple[Compiled, None]:
        """The model on a mesh with the hole cut out, and its geometry as the unknowns (start:
        the hole as given)."""
        base = self.base
        ex, hole = base.experiment, self.hole
        size = self.h or _mesh_size(base, [hole])
        mesh = domain_mesh(ex, size, self.element, holes=[hole])
        model = MeasuredModel(ex, base.obs, mesh=mesh, h=size, linear_solver=base.linear_solver)
        param = ShapeGeometry(jf.morph(mesh, [hole]), hole.params[None], scale=0.5 * base.spacing, rotate=True,
                              mesh=mesh, outside=_seen(base, self.subsets), min_axis=0.1 * base.spacing)
        return Compiled(model, param), None

    def at(self, shapes, element: str) -> HoleHypothesis:
        return hole_hypothesis(self.base, shapes[0], h=self.h, element=element, subsets=self.subsets)


def _subset(base: MeasuredModel) -> float | None:
    """The side of the square DIC subset around each tracked point (``measurement.subset``,
    length unit), None where unknown (a solid's, or an older bundle's)."""
    ex = base.experiment
    subset = getattr(ex, "subset", None)
    return subset if subset is not None and getattr(ex, "dim", 2) == 2 else None


def _seen(base: MeasuredModel, subsets: bool = True) -> np.ndarray:
    """Where material was seen, ``(m, 2)``: the tracked points, or with a known subset samples of
    their subsets' squares (:func:`~refine.diagnosis.subsets.seen_material`): a hole keeps half a
    subset away from every tracked point, whose whole subset was correlated on material."""
    return seen_material(base.obs.reference, _subset(base) if subsets else None)


def subset_start(base: MeasuredModel, shape):
    """Where the subsets put a hole candidate ``shape``: with a known subset and points on a
    lattice, the ellipse between the correlated and the failed subsets around the candidate
    (:func:`~refine.diagnosis.subsets.hole_from_subsets`), else ``shape`` as it is. The data fit
    starts there (a hole of the CFRP coupon started from the points' gap grew to the nearest
    tracked point, +28 % in area, where the data barely told the two apart)."""
    subset = _subset(base)
    if subset is None:
        return shape
    reach = max(shape.axes) + subset + base.spacing
    evidence = hole_from_subsets(base.obs.reference, subset, shape.centre, reach)
    if evidence is None:
        return shape
    cx, cy, a, b, angle = map(float, evidence.params)
    return Hole((cx, cy), (a, b), angle)


def hole_hypothesis(base: MeasuredModel, shape, h: float | None = None, element: str = "tri3",
                    subsets: bool = True) -> HoleHypothesis:
    """The :class:`HoleHypothesis` started at ``shape`` (a :class:`Hole` or
    :class:`~refine.diagnosis.shapes.RegionShape`), kept inside the domain and shrunk until no
    tracked point (with a known subset and ``subsets``: no tracked point's subset, :func:`_seen`) lies inside it
    (material was seen there). A candidate that has to shrink below
    ``HOLE_MIN_SHRINK`` of its size has tracked material near its middle and is no hole
    (:class:`NotApplicable`: such a start is a pinhole that needs a very fine mesh, and its fit
    costs minutes to lose)."""
    ex, obs = base.experiment, base.obs
    start = shape.clamped(ex.domain, base.spacing)
    (cx, cy), (a, b), ang = start.centre, start.axes, start.angle
    pts = _seen(base, subsets)
    size = max(a, b)
    # clear of the points by a fifth of a spacing (room for the mesh between them and the hole); of
    # the subsets' outlines (the points half a subset farther) by a fiftieth: a start short of
    # the subsets' walls leaves a fit stalled against them short of the hole (LM turns back at walls)
    clear = 0.2 * base.spacing
    if subsets and _subset(base) is not None:  # the largest scaled copy free of the subsets
        clear = 0.02 * base.spacing
        a, b = np.multiply((a, b), min(1.0, _free_scale(jf.Ellipse(cx, cy, a, b, ang), pts, clear)))
    for _ in range(30):
        e = jf.Ellipse(cx, cy, a, b, ang)
        if not e.contains(pts).any() and np.min(np.linalg.norm(pts - e.to_curve(pts), axis=1)) > clear:
            break
        a, b = 0.9 * a, 0.9 * b
    else:
        a = b = 0.0  # no start free of tracked points
    if max(a, b) < HOLE_MIN_SHRINK * size:
        near = obs.reference[np.argmin(np.linalg.norm(obs.reference - [cx, cy], axis=1))]
        raise NotApplicable(f"no hole at ({cx:.1f}, {cy:.1f}): the tracked point at ({near[0]:.1f}, {near[1]:.1f}) "
                            "lies near its middle (material was seen there)")
    return HoleHypothesis(base, jf.Ellipse(cx, cy, a, b, ang), h, element, subsets)


def _free_scale(e: jf.Ellipse, pts: np.ndarray, gap: float) -> float:
    """The largest factor by which ``e`` may be scaled about its centre and keep every point of
    ``pts`` ``(m, 2)`` outside it, about ``gap`` (length unit) clear of its outline."""
    cx, cy, a, b, ang = map(float, e.params)
    d = pts - [cx, cy]
    c, s = np.cos(ang), np.sin(ang)
    rho = np.hypot((d @ [c, s]) / a, (d @ [-s, c]) / b)
    return float(rho.min() - gap / min(a, b))


def fit_hole(base: MeasuredModel, shape, fit_mask, hold_mask, sigma, h: float | None = None,
             element: str = "tri3", restarts=()) -> Fitted:
    """A hole (:func:`hole_hypothesis`), its centre, axes and orientation fitted, and refitted
    from ``restarts`` at its fitted centre (:func:`~refine.diagnosis.restarts.best_of_restarts`,
    as :func:`~refine.diagnosis.regions.fit_regions` does; none by default: the diagnosis's
    search fits each candidate once), the lowest misfit kept.

    With the bundle's subset known, the hole is first fitted from where the subsets put it
    (:func:`subset_start`) keeping clear of the tracked points only; where that fit covers part
    of a tracked point's subset (material was correlated there), it is fitted again with every
    subset kept out, from two starts, each shrunk clear of the subsets: the first fit, and the
    subsets' own ellipse; the one with the lower misfit is kept. A fit started at the subsets'
    walls stops at the first it meets (Levenberg-Marquardt turns back at a wall), short of the
    best shape on the walls: from the subsets' ellipse a generated elongated hole stopped at
    chi2 ten times the free fit's, from the first fit shrunk the CFRP coupon's stopped 20 %
    higher than from the subsets' round ellipse."""
    return best_of_restarts(_fit_hole_once(base, shape, fit_mask, hold_mask, sigma, h, element), [shape],
                            fit_mask, hold_mask, restarts)


def _fit_hole_once(base: MeasuredModel, shape, fit_mask, hold_mask, sigma, h, element) -> Fitted:
    """:func:`fit_hole` without its restarts."""
    if _subset(base) is None:
        return fit(hole_hypothesis(base, shape, h, element), fit_mask, hold_mask, sigma)
    start = subset_start(base, shape)
    free = fit(hole_hypothesis(base, start, h, element, subsets=False), fit_mask, hold_mask, sigma)
    found = free.shapes[0]
    if subset_distance(base.obs.reference, found.params, _subset(base)).min() > 0:
        return replace(free, hypothesis=replace(free.hypothesis, subsets=True))
    fits = [fit(hole_hypothesis(base, s, h, element), fit_mask, hold_mask, sigma) for s in (found, start)]
    return min(fits, key=lambda f: f.chi2_fit if np.isfinite(f.chi2_fit) else np.inf)


@dataclass(frozen=True, eq=False)
class EmptyRegion:
    """A fitted softer region named a hole (:func:`named_hole`): its shapes read as holes, its
    fit (model, moduli, misfits) kept as they are."""

    region: object
    remeshable = False

    @property
    def law(self) -> str:
        return self.region.law

    def cause_of(self, shapes) -> str:
        return "hole"

    def shapes_at(self, compiled: Compiled, z) -> tuple[Hole, ...]:
        return tuple(Hole(s.centre, s.axes, s.angle) for s in self.region.shapes_at(compiled, z))

    def at(self, shapes, element: str) -> None:
        return None


def stiffness_indistinguishable_from_zero(soft: Fitted, below: float) -> bool:
    """Whether a one-region softer fit's relative elasticity is indistinguishable from zero: below
    ``below`` (a region that carries almost no load moves the points as a hole does), or within
    two standard errors of zero (``z_std`` of its log ratio at least 1/2)."""
    ratio = soft.shapes[0].ratio
    z_std = None if soft.z_std is None else float(soft.z_std[0])
    return ratio < below or (z_std is not None and np.isfinite(z_std) and z_std >= 0.5)


def named_hole(soft: Fitted, points, below: float) -> Fitted:
    """A one-region softer ellipse whose stiffness is indistinguishable from zero
    (:func:`stiffness_indistinguishable_from_zero`) and which holds no tracked point (``points
    (n, 2)``: no material was seen inside) is a hole, and is named one (its fit unchanged);
    anything else is returned as it is."""
    if soft.cause != "softer-region" or len(soft.shapes) != 1 or soft.shapes[0].kind != "ellipse":
        return soft
    if not stiffness_indistinguishable_from_zero(soft, below) or soft.shapes[0].geometry().contains(points).any():
        return soft
    hypothesis = EmptyRegion(soft.hypothesis)
    return replace(soft, hypothesis=hypothesis, shapes=tuple(Hole(s.centre, s.axes, s.angle) for s in soft.shapes))
