"""Extended models the diagnosis tries, each fitted by exact gradients.

A hypothesis is a way the initial model may be wrong: regions of other stiffness (ellipses or
rectangles whose centre, axes or sides, orientation and moduli are fitted), a hole (an ellipse whose centre, axes and
orientation are fitted), or a different material law. Each builds its own model (a mesh that
follows the shapes), is fitted on the guide points chosen for fitting, and is scored on held-out
guide points and by an information criterion.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

import jaxfem as jf

from refine.model.objective import Compiled
from refine.optimize.levenberg_marquardt import levenberg_marquardt
from refine.model.measured import MeasuredModel, domain_mesh
from refine.model.parametrize import Combined, RegionModuli, ShapeGeometry, UniformParameter, make_shape


@dataclass
class Fitted:
    """A fitted hypothesis.

    Attributes:
        cause: ``"none"``, ``"stiffer-region"``, ``"softer-region"``, ``"hole"``, ``"regions"`` or
            ``"material-law"``.
        k: number of fitted parameters.
        chi2_fit: whitened squared misfit on the fitting points; chi2_holdout: on held-out points.
        bic: chi2_fit + k ln(n_fit).
        predicted: displacements of all points ``(frames, n_points, dim)``.
        shapes: fitted shapes ``[(kind, cx, cy, a, b, angle, relative_elasticity)]``, kind
            ``"ellipse"`` (a, b semi-axes), ``"rectangle"`` (a, b half sides) or ``"hole"``.
        law: the material law of the model.
    """

    cause: str
    k: int
    chi2_fit: float
    chi2_holdout: float
    bic: float
    predicted: np.ndarray
    shapes: list = field(default_factory=list)
    law: str = ""
    result: object = None
    model: object = None
    theta: object = None
    compiled: object = None
    z: object = None
    shapes_from: object = None
    z_std: object = None
    remesh: object = None

    def describe(self) -> str:
        parts = [f"{s[0]} at ({s[1]:.1f}, {s[2]:.1f}) {'half sides' if s[0] == 'rectangle' else 'axes'} "
                 f"({s[3]:.1f}, {s[4]:.1f}) angle {np.degrees(s[5]):.0f} deg ratio {s[6]:.2f}" for s in self.shapes]
        return f"{self.cause} [{'; '.join(parts) or self.law}] chi2 {self.chi2_fit:.0f} holdout {self.chi2_holdout:.0f}"


def _chi2(pred, obs, points, sigma) -> float:
    meas = obs.displacements[:, points]
    ok = np.isfinite(meas).all(-1)
    r = ((pred[:, points] - np.nan_to_num(meas)) / sigma)[ok]
    return float(np.sum(r * r))


def _fit(cause, compiled: Compiled, fit_mask, hold_mask, sigma, z0=None, shapes_from=None, **kw) -> Fitted:
    """Fit by Levenberg-Marquardt on the fitting points, score on both sets."""
    res = levenberg_marquardt(compiled, fit_mask, sigma, z0=z0)
    z = np.asarray(res.values["z"])
    pred = compiled.predict(z)
    obs = compiled.model.obs
    chi2 = _chi2(pred, obs, fit_mask, sigma)
    n = int(np.isfinite(obs.displacements[:, fit_mask]).all(-1).sum()) * pred.shape[-1]
    k = compiled.param.size
    return Fitted(cause, k, chi2, _chi2(pred, obs, hold_mask, sigma), chi2 + k * np.log(max(n, 2)), pred,
                  shapes=shapes_from(z) if shapes_from else [], result=res, model=compiled.model,
                  theta=compiled.param.apply(compiled.theta, z), compiled=compiled, z=z,
                  shapes_from=shapes_from, **kw)


def refit(f: Fitted, points, hold_mask, sigma, max_remesh: int = 2, element: str = "tri3") -> Fitted:
    """The same hypothesis refitted on other points (e.g. all guide points), with the standard
    errors of its unknowns.

    A hypothesis with fitted shapes is remeshed at them first and refitted from there, again
    while its shapes still move by more than a fifth of the element size: a morph of the first
    mesh can only take a shape so far (its cells distort, then invert), which leaves a region
    fitted too small with too large a ratio, or a hole too small. The new meshes use ``element``
    (quadratic triangles are far less stiff in a strongly strained region than linear ones at
    the same size). Without shapes the compiled model is reused."""
    g = None
    if f.remesh is not None and f.shapes:
        start = f
        for _ in range(max(1, max_remesh)):
            try:
                h = f.remesh(start.shapes, points, hold_mask, element)
            except Exception:  # noqa: BLE001 - e.g. a remesh at a runaway ratio that no longer solves
                h = None
            if h is None or not np.isfinite(h.chi2_fit):
                break
            if g is None or h.chi2_fit < g.chi2_fit:
                g = h
            moved = max(_moved(a, b) for a, b in zip(start.shapes, h.shapes))
            if moved < 0.2 * f.model.h:
                break
            start = h
    if g is None:  # no shapes, or no remesh could be fitted: refit the compiled model as it is
        g = _fit(f.cause, f.compiled, points, hold_mask, sigma, z0=f.z, shapes_from=f.shapes_from, law=f.law)
    g.z_std = standard_errors(g, points, sigma)
    return g


def _moved(s, t) -> float:
    """How far a fitted shape ``(kind, cx, cy, a, b, angle, ratio)`` moved: its largest change of
    centre or axis, or of the outline by its turn (``|a - b|`` times the angle)."""
    turn = abs(np.angle(np.exp(2j * (t[5] - s[5])))) / 2 * abs(t[3] - t[4])
    return float(max(np.max(np.abs(np.subtract(s[1:5], t[1:5]))), turn))


def standard_errors(f: Fitted, points, sigma) -> np.ndarray:
    """Standard errors of the fitted unknowns z from the Gauss-Newton covariance
    (J^T J)^-1 scaled by the reduced chi^2 (at least 1): how well the data fix each one."""
    obs = f.compiled.model.obs
    valid = np.isfinite(obs.displacements[:, points]).all(-1)
    J = f.compiled.jacobian(f.z)[:, points][valid].reshape(-1, len(f.z)) / sigma
    n, k = J.shape
    scale = max(f.chi2_fit / max(n - k, 1), 1.0)
    try:
        return np.sqrt(np.clip(np.diag(np.linalg.inv(J.T @ J)), 0, None) * scale)
    except np.linalg.LinAlgError:
        return np.full(k, np.nan)


def baseline(model: MeasuredModel, fit_mask, hold_mask, sigma) -> Fitted:
    """The initial model, nothing fitted (under pure displacement driving a uniform modulus
    cancels out, so there is nothing to fit without measured forces)."""
    pred = np.asarray(model.predict(model.params()))
    chi2 = _chi2(pred, model.obs, fit_mask, sigma)
    return Fitted("none", 0, chi2, _chi2(pred, model.obs, hold_mask, sigma), chi2, pred, law=model.experiment.law,
                  model=model, theta=model.params())


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


class NotApplicable(ValueError):
    """A hypothesis the data rule out before any fit (e.g. a hole where material was tracked)."""


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


ALTERNATIVE_LAWS = {"neo-hookean": ("mooney-rivlin", "saint-venant-kirchhoff"),
                    "mooney-rivlin": ("neo-hookean", "saint-venant-kirchhoff"),
                    "saint-venant-kirchhoff": ("neo-hookean", "mooney-rivlin"),
                    "linear-elastic": ("neo-hookean",)}


def fit_law(base: MeasuredModel, law: str, fit_mask, hold_mask, sigma) -> Fitted:
    """A different homogeneous material law, with its Poisson's ratio (and for Mooney-Rivlin its
    second-invariant share) fitted."""
    from dataclasses import replace

    ex = replace(base.experiment, law=law)
    model = MeasuredModel(ex, base.obs, mesh=base.mesh, h=base.h)
    parts = [UniformParameter("nu", float(ex.nu), 0.0, 0.499)]
    if law == "mooney-rivlin":
        parts.append(UniformParameter("c01_fraction", 0.25, 0.0, 0.95))
    param = Combined(tuple(parts))
    return _fit("material-law", Compiled(model, param), fit_mask, hold_mask, sigma, law=law)
