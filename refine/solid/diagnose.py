"""The 3D diagnosis of a cup holder's bottom (the paper's Sec. 4): is anything wrong beyond the
noise, where (candidates from gaps in the bottom's points and from its measured strain), is it a
hole (fitted by exact implicit gradients through a morph, remeshed while it moves), how much better
the held-out points are predicted; the found hole refitted in the global model (the whole cup
holder held by the fixture's points: the local model, which leaves the wall out, gets the hole's
size a quarter too small) with a uniform modulus fitted beside it (the coarse model is stiffer
than the body; with the modulus known, the fit enlarged the hole to soften it: +18 % area on
noise-free data, -1 % with it fitted); the report.

The local model (:mod:`refine.solid.local`) is fitted on the bottom face's ``guide`` points and
scored on its ``validate`` points; the null test weighs the global model's ``guide`` residuals (no
hole, a uniform modulus fitted) against the noise and that model's discretisation error
(:mod:`refine.solid.null_level`: the local model, which leaves the wall out, missed a sound cup
holder's data by 14 x the noise's chi2), or with ``SolidConfig.null_model = "local"`` the local
model's against the noise and the boundary points' noise carried through it
(:func:`refine.diagnosis.noise.null_test`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

import jaxfem as jf
from jaxfem.surface import project_to_surface

from refine.bundle.domains import PolygonDomain
from refine.bundle.io import Bundle
from refine.bundle.observations import Observations
from refine.bundle.roles import point_spacing
from refine.diagnosis.candidates import missing_point_regions, strain_regions
from refine.diagnosis.fitted import Fitted, NotApplicable, fit, refit
from refine.diagnosis.noise import estimate_noise
from refine.diagnosis.shapes import Hole
from refine.diagnosis.uncertainty import discretisation_errors, shape_errors, total_errors
from refine.exceptions import ObservationError
from refine.measures import Residuals
from refine.solid.cup import CupShape, bottom_points, check_closed, cup_shape
from refine.solid.edge import EdgeEvidence, evidence_near, grid_lattice, NoLattice
from refine.solid.inclusion_diagnosis import InclusionDiagnosis, diagnose_inclusion, fills_hull, inclusion_report
from refine.solid.initial import initial_fit, initial_null
from refine.solid.hole_area import extrapolated_area, with_plan_and_layers
from refine.solid.local import HOLE_HEADROOM, Local, SolidHole, Whole
from refine.solid.null_level import global_null
from refine.solid.start import best_start, bracket_starts


@dataclass(frozen=True)
class SolidConfig:
    """Settings of the 3D diagnosis: ``h`` the local and global models' element size (length unit;
    None: :func:`model_h`), ``alpha`` the null test's level, ``max_candidates`` holes tried,
    ``max_remesh`` remeshes of the global model's moving hole, ``linear_solver``;
    ``global_modulus``: the global refit fits a uniform modulus beside the hole (it absorbs the
    model's discretisation stiffness, which a known modulus turns into a hole too large);
    ``local_remesh``: remeshes of the local model's hole (0: its fit on the first mesh's morph
    decides, and the global refit, which remeshes anyway, sizes it; each remesh is a compilation);
    ``edge_slack``: with the
    bottom's points on a painted grid's lattice, the missing crossings of a hole's gap bracket its
    edge (:mod:`refine.solid.edge`): both fits start from the ellipse between them and keep every
    missing crossing within ``edge_slack`` grid steps of the hole (a tracker loses crossings within
    about 0.7 pitch of a hole's edge: :mod:`refine.solid.start`); None: no edge evidence.
    ``discretisation_error``: the global model's mesh's share of the found hole's error, reported
    beside its standard error, and the hole's area extrapolated to a fine mesh (three more fits,
    the plan sqrt(2) coarser and one more element through the floor, each alone and both:
    :func:`refine.solid.hole_area.with_plan_and_layers`). ``null_model``: which model
    the null test weighs against the noise: ``"global"``, the whole cup holder without a hole, a
    uniform modulus fitted, its discretisation error in the null level as the 2D diagnosis's
    (:func:`refine.solid.null_level.global_null`; two global solves: the local model, which leaves
    the wall out, missed a sound cup's data by 14 x the noise's chi2); ``"local"``: the local
    model's, with the drive's noise carried through it (before). ``hole_ratio``: a hole's models
    (local and global, remeshed as it moves) have elements along its curve of at most this many
    times its smallest radius of curvature, graded to ``h`` away from it
    (:meth:`refine.solid.local.Local.hole_h`); None: ``h`` there too."""

    h: float | None = None
    alpha: float = 0.01
    max_candidates: int = 2
    max_remesh: int = 4
    linear_solver: str = "auto"
    global_modulus: bool = True
    local_remesh: int = 0
    edge_slack: float | None = 0.75
    discretisation_error: bool = True
    null_model: str = "global"
    hole_ratio: float | None = None

    def __post_init__(self):
        if self.null_model not in ("global", "local"):
            raise ValueError(f"SolidConfig.null_model is 'global' or 'local', not {self.null_model!r}")


@dataclass
class SolidDiagnosis:
    """What the 3D diagnosis found: ``shape`` (the cup), ``local`` (its recipe), the initial
    local model's fit ``base``, the ``null`` test, the ``candidates`` tried, the hole fitted
    (``hole``, None where none could be) and the chosen fit (``chosen``: the hole or ``base``),
    seconds per stage, the found hole refitted in the global model (``whole``; the finding), how the
    null test was made (``null_level``: :func:`refine.solid.null_level.global_null`'s, with the
    local model's own misfit ratio; None: the local model's null test), the number of ``gaps`` in
    the bottom's points inside the floor (a hole is tried where there is one, whatever the null
    test says)."""

    shape: CupShape
    local: Local
    base: Fitted
    null: object
    candidates: list
    hole: Fitted | None
    chosen: Fitted
    seconds: dict = field(default_factory=dict)
    whole: Fitted | None = None
    null_level: dict | None = None
    gaps: int = 0

    @property
    def found(self) -> bool:
        return self.chosen is not self.base


def squeeze_force(obs: Observations) -> np.ndarray:
    """The measured total force on the bottom face per frame, ``(n_frames, 3)``: forces.csv's side
    ``back`` (the mesh's z-min face)."""
    if obs.forces is None or "back" not in obs.forces.edges:
        raise ObservationError("a cup holder's diagnosis needs the squeeze force on its bottom: forces.csv with the "
                               "side 'back' (the z-min face of the mesh), one row per frame")
    return obs.forces.on("back")


def _on_surface(mesh: jf.Mesh, obs: Observations, tol: float) -> None:
    """Every tracked point lies on the body's surface, within ``tol`` (length unit), or an error
    names the farthest."""
    _, d = project_to_surface(mesh, obs.reference)
    if (d > tol).any():
        worst = int(np.argmax(d))
        raise ObservationError(f"{int((d > tol).sum())} points are not on the model's surface (the farthest, point "
                               f"{obs.ids[worst]}, is {d[worst]:.3g} from it, more than {tol:.3g}); check the mesh's "
                               "units and placement against the points")


def local_recipe(bundle: Bundle, cfg: SolidConfig) -> tuple[CupShape, Local, np.ndarray]:
    """The cup's shape, the local model's recipe and which points ``(n,)`` bool are on the bottom."""
    exp, obs = bundle.experiment, bundle.observations
    if exp.kind != "solid" or obs is None or obs.dim != 3:
        raise ObservationError("the 3D diagnosis takes a solid bundle with 3D points")
    root = "" if bundle.root is None else f"{bundle.root}/"
    mesh = jf.read_mesh(f"{root}{exp.domain.path}")
    check_closed(mesh)
    shape = cup_shape(mesh)
    s = point_spacing(obs.reference)
    _on_surface(mesh, obs, 0.5 * s)
    on = bottom_points(shape, obs.reference, tol=max(3 * (exp.noise_std or 0.0), 0.05 * s))
    X = obs.reference[on] - shape.offset
    # the wall holds the floor's edge: every point under it drives the local model, whatever role
    # the bundle gave it (a tracked bundle's outer ring is one row of points)
    roles = np.where(np.hypot(X[:, 0], X[:, 1]) >= shape.r_in - 0.5 * point_spacing(X[:, :2]), "boundary",
                     obs.roles[on])
    for role in ("boundary", "guide", "validate"):
        if not (roles == role).any():
            raise ObservationError(f"no {role} point on the bottom's outer face (z = {shape.z0:g}): the local "
                                   "model needs boundary points under the wall, guide and validate points inside")
    X[:, 2] = 0.0  # on the face's plane (a depth's noise would put a point outside the slab)
    local_obs = Observations(obs.ids[on], X, roles, obs.displacements[:, on])
    h = cfg.h or model_h(point_spacing(X[:, :2]), shape.bottom)
    return shape, Local(shape, exp, local_obs, squeeze_force(obs), h, cfg.linear_solver,
                        hole_ratio=cfg.hole_ratio), on


def model_h(spacing: float, bottom: float) -> float:
    """The models' element size (length unit) by default: 1.5 point ``spacing``s, but not below
    0.4 of the ``bottom``'s thickness (1.2 mm for a 3 mm bottom). Finer meshes cost about h^-3 in
    the global model (0.9 mm, 1.5 spacings of a 0.6 mm grid: 66k unknowns); the report gives the
    mesh's discretisation error (a refit sqrt(2) coarser) beside the standard error, to judge
    whether a finer ``h`` is needed."""
    return max(1.5 * spacing, 0.4 * bottom)


def hole_candidates(local: Local, base: Fitted, sigma: float, max_n: int) -> list[Hole]:
    """Where a hole may be, largest first: gaps in the bottom's points inside the floor, then
    patches of abnormally high measured in-plane strain (the paper's cue), as starting holes."""
    xy = local.obs.reference[:, :2]
    s = point_spacing(xy)
    found = point_gaps(local)
    meas = np.nan_to_num(local.obs.displacements[-1, :, :2])  # the frame of most motion
    found += [c for c in strain_regions(xy, meas, base.predicted[-1, :, :2], sigma, np.pi * s * s, max_n)
              if c.sign < 0]
    # started as large as the points allow (a gap's ellipse stops short of its points; the start
    # is shrunk until none lies inside): a morph grows a hole only so far before a remesh
    return [Hole(tuple(c.centroid), tuple(np.asarray(c.axes) + 0.5 * s), float(c.angle)) for c in found[:max_n]]


def point_gaps(local: Local) -> list:
    """Gaps in the bottom's points inside the floor (regions where material is not seen,
    :func:`refine.diagnosis.candidates.missing_point_regions`), largest first."""
    xy = local.obs.reference[:, :2]
    ring = np.linspace(0, 2 * np.pi, 97)[:-1]
    floor = PolygonDomain(tuple(map(tuple, local.shape.r_in * np.c_[np.cos(ring), np.sin(ring)])))
    # a square grid leaves at most 0.71 pitch; at 0.9 the patch of a hole of 1.9 x 1.5 mm in a 1.2 mm
    # grid is under the disc of one pitch that a candidate needs
    return missing_point_regions(xy, floor, gap=0.8)


def diagnose_solid(bundle: Bundle, cfg: SolidConfig = SolidConfig(), log=print) -> SolidDiagnosis | InclusionDiagnosis:
    """Diagnose a cup holder's bottom (see the module); a body without a cavity (its mesh fills its
    convex hull: a block) for an ellipsoidal inclusion instead
    (:func:`refine.solid.inclusion_diagnosis.diagnose_inclusion`)."""
    if thin_wall_reason(bundle) is not None:
        return diagnose_inclusion(bundle, log=log)
    t0 = time.perf_counter()
    shape, local, _ = local_recipe(bundle, cfg)
    obs = local.obs
    guide, validate = obs.roles == "guide", obs.roles == "validate"
    sigma = bundle.experiment.noise_std or estimate_noise(obs)
    model, _ = local.model(headroom=HOLE_HEADROOM)  # the holes' meshes share its programs
    base = initial_fit(model, obs, sigma)
    level = None
    if cfg.null_model == "global":
        null, level = global_null(bundle, local, guide, sigma)
        level["local_ratio"] = base.chi2_fit / max(Residuals.at(obs.displacements, guide).n, 1)
    else:  # the local model's (SolidConfig checks the name)
        null = initial_null(base, obs, sigma)
    seconds = {"initial": time.perf_counter() - t0}
    log(f"local model: {model.mesh.n_cells} cells, {len(obs.ids)} bottom points; the {cfg.null_model} model's "
        f"misfit {null.ratio:.2f} x the null level's (p = {null.p_value:.2g}; discretisation {null.sigma_model:.3g})")
    tried, best = [], None
    # a gap in the points inside the floor is evidence of its own (material not seen): the global
    # null test's modulus absorbs much of a small hole at coarse noise, so the hole is tried there
    # too; the choice rests on the fit and the held-out points
    gaps = len(point_gaps(local))
    if null.p_value < cfg.alpha or gaps:
        for start in hole_candidates(local, base, sigma, cfg.max_candidates):
            edge = grid_edge(local, start, cfg, log)
            if edge is not None:
                start = Hole(tuple(edge.ellipse[:2]), tuple(edge.ellipse[2:4]), float(edge.ellipse[4]))
            if any(same_start(start, t) for t in tried):
                # two candidates (a gap and its strain patch) snapped to one gap's edge ellipse:
                # the same fit again
                log(f"  candidate at ({start.centre[0]:.1f}, {start.centre[1]:.1f}): the start of one tried already")
                continue
            try:
                hyp = SolidHole(local, local.hole_from(start), edge=edge)
            except (NotApplicable, jf.MeshError) as e:
                log(f"  candidate at ({start.centre[0]:.1f}, {start.centre[1]:.1f}): {e}")
                continue
            tried.append(start)
            f = fit(hyp, guide, validate, sigma)
            if cfg.local_remesh:
                f = refit(f, guide, validate, sigma, max_remesh=cfg.local_remesh, element="tet10")
            log(f"  {f.describe()}")
            if best is None or f.chi2_fit < best.chi2_fit:
                best = f
    seconds["hole"] = time.perf_counter() - t0 - seconds["initial"]
    chosen, whole = base, None
    if best is not None and best.bic < base.bic and best.chi2_holdout < base.chi2_holdout:
        chosen = best
        whole = refit_whole(bundle, local, best.shapes[0], sigma, cfg, best.hypothesis.edge, log, seconds)
        log(f"  global model: {whole.describe()}")
        seconds["global_fit"] = time.perf_counter() - t0 - sum(seconds.values())
    return SolidDiagnosis(shape, local, base, null, tried, best, chosen, seconds, whole, level, gaps)


def same_start(a: Hole, b: Hole) -> bool:
    """Whether two starting holes are the same ellipse (to round-off): the same fit."""
    return bool(np.allclose([*a.centre, *a.axes, a.angle], [*b.centre, *b.axes, b.angle], rtol=0, atol=1e-9))


def grid_edge(local: Local, start: Hole, cfg: SolidConfig, log=print) -> EdgeEvidence | None:
    """The painted grid's evidence of a hole near the candidate ``start`` (:mod:`refine.solid.edge`),
    None where ``cfg.edge_slack`` is None, the bottom's points lie on no lattice or no gap of
    missing crossings inside the floor is near."""
    if cfg.edge_slack is None:
        return None
    xy = local.obs.reference[:, :2]
    try:
        lattice = grid_lattice(xy)
    except NoLattice as e:
        log(f"  no edge evidence: {e}")
        return None
    reach = max(start.axes) + 2 * lattice.step
    return evidence_near(lattice, start.centre, reach, local.shape.r_in, cfg.edge_slack)


def thin_wall_reason(bundle: Bundle, share: float = 0.8) -> str | None:
    """Why the local model of an observed thin wall (this module's strategy: a through-hole in
    the wall, refitted in the whole body) does not apply to a solid bundle; None where it does.

    It applies where the body has a floor (a wall thinner than half the body's height, standing
    inside a rim: an inner wall well inside the outer one, as :func:`refine.solid.cup.cup_shape`
    measures them with the axis along z) and at least ``share`` of the guide points lie on that
    floor's outer face (the face the camera sees). Any other body (a block, a bracket, a tube, a
    body seen on several faces) goes to the engine of :mod:`refine.solid.engine`."""
    domain, root = bundle.experiment.domain, "" if bundle.root is None else f"{bundle.root}/"
    if bundle.experiment.kind != "solid" or not hasattr(domain, "path") or bundle.observations is None:
        return "not a solid bundle with a mesh and tracked points"
    try:
        shape = cup_shape(jf.read_mesh(f"{root}{domain.path}"))
    except ObservationError as e:
        return str(e)
    if not (shape.bottom < 0.5 * shape.height and shape.r_in <= 0.9 * shape.r_out):
        return (f"no thin wall inside a rim (floor {shape.bottom:.3g} of height {shape.height:.3g}, inner radius "
                f"{shape.r_in:.3g} of {shape.r_out:.3g})")
    obs = bundle.observations
    guide = obs.roles == "guide"
    tol = max(3 * (bundle.experiment.noise_std or 0.0), 0.05 * point_spacing(obs.reference))
    on = bottom_points(shape, obs.reference, tol)
    seen = float((on & guide).sum()) / max(int(guide.sum()), 1)
    if seen < share:
        return f"{100 * seen:.0f} % of the guide points lie on the floor's outer face (the strategy needs {100 * share:.0f} %)"
    return None


def refit_whole(bundle: Bundle, local: Local, hole: Hole, sigma: float, cfg: SolidConfig,
                edge: EdgeEvidence | None = None, log=print, seconds: dict | None = None) -> Fitted:
    """The local model's hole refitted in the global model (:class:`~refine.solid.local.Whole`),
    held by the fixture's points, on every bottom point but the ``validate`` ones, scored on all
    ``validate`` points. With the grid's ``edge`` evidence the refit starts from the best of a few
    ellipses along its bracket (:mod:`refine.solid.start`; the local model, which leaves the wall
    out, sizes the hole wrongly: -37 % to +92 % on the benchmark's cases), from the modulus that
    start fitted, and keeps to it. With ``cfg.discretisation_error`` the mesh's share of the
    hole's error is estimated (its seconds into ``seconds["discretisation"]``)."""
    whole, on = Whole.of(local, bundle.observations)
    held = whole.obs
    guide = (held.roles == "guide") & on
    validate = held.roles == "validate"
    e, E = jf.Ellipse(*hole.centre, *hole.axes, hole.angle), None
    starts = [] if edge is None else bracket_starts(local, edge)
    if starts:
        e, E = best_start(whole, starts, guide, sigma, log)
    start = SolidHole(whole, e, cfg.global_modulus, edge, E)
    f = refit(fit(start, guide, validate, sigma), guide, validate, sigma, max_remesh=cfg.max_remesh, element="tet10")
    if cfg.discretisation_error:
        t0 = time.perf_counter()
        f = with_plan_and_layers(f, guide, validate, sigma)  # the mesh's share: its plan and its layers
        if seconds is not None:
            seconds["discretisation"] = time.perf_counter() - t0
    return f


def report(d: SolidDiagnosis) -> dict:
    """report.json's content: the cause, the hole's 3D centroid (mesh frame, mid-thickness), axes,
    angle, area and volume with standard errors, the null test, the held-out gain, seconds (a
    body's inclusion: :func:`refine.solid.inclusion_diagnosis.inclusion_report`)."""
    if isinstance(d, InclusionDiagnosis):
        return inclusion_report(d)
    n = lambda m: max(1, 3 * d.local.obs.n_frames * m.sum())  # noqa: E731
    rms = lambda f, m: float(np.sqrt(f.chi2_holdout / n(m)) * f.sigma)  # noqa: E731
    validate = d.local.obs.roles == "validate"
    out = {"cause": d.chosen.cause, "null_test": {"statistic": d.null.statistic, "dof": d.null.dof,
                                                   "p_value": d.null.p_value, "noise_std": d.null.sigma,
                                                   "ratio": d.null.ratio, "model_error_std": d.null.sigma_model,
                                                   "model": "local" if d.null_level is None else "global",
                                                   **({} if d.null_level is None else {"level": d.null_level})},
           "point_gaps": d.gaps,
           "local_model": {"cells": int(d.base.model.mesh.n_cells), "h": d.local.h,
                           "points": int(len(d.local.obs.ids))},
           "validate_rms": {"initial": rms(d.base, validate)}, "findings": [], "seconds": d.seconds}
    if d.found:
        out["validate_rms"]["refined"] = rms(d.chosen, validate)
        out["held_out_gain"] = out["validate_rms"]["initial"] / max(out["validate_rms"]["refined"], 1e-300)
        out["findings"].append({**hole_entry(d, d.whole or d.chosen), "local_model": hole_entry(d, d.chosen),
                                "edge": edge_entry(getattr(d.chosen.hypothesis, "edge", None),
                                                   (d.whole or d.chosen).shapes[0])})
    return out


def hole_entry(d: SolidDiagnosis, f: Fitted) -> dict:
    """A fitted hole as report.json lists it: centroid (mesh frame, mid-thickness), axes, angle,
    area, volume and their standard errors. Where the mesh's discretisation error was estimated
    with its sign, ``area`` (and ``volume``) is the area cut extrapolated to a fine mesh
    (:func:`refine.solid.hole_area.extrapolated_area`; its parts in ``area_extrapolation``) and
    ``area_ellipse`` the fitted ellipse's; the errors are the ellipse's (the discretisation error
    stays the size of the mesh's effect: what the extrapolation leaves is not estimated)."""
    s = f.shapes[0]
    err = (shape_errors(f) or [None])[0]
    disc = (discretisation_errors(f) or [None])[0]
    ellipse, _ = s.outline()
    fine = extrapolated_area(f) if isinstance(f.hypothesis, SolidHole) else None
    area = ellipse if fine is None else fine["area"]
    c = np.array([*s.centre, 0.5 * d.shape.bottom]) + d.shape.offset
    return {"kind": "hole", "through": "bottom", "centroid": c.tolist(), "axes": list(map(float, s.axes)),
            "angle": float(s.angle), "area": float(area), "volume": float(area * d.shape.bottom),
            **({} if fine is None else {"area_ellipse": float(ellipse), "area_extrapolation": fine}),
            **({"E": float(np.mean(f.theta["E"]))} if getattr(f.hypothesis, "free_modulus", False) else {}),
            "std": None if err is None else {**err.to_json(), "volume": None if err.area is None
                                             else round(float(err.area * d.shape.bottom), 4)},
            **({} if disc is None else {"discretisation": disc.to_json(),
                                        "total_std": total_errors(err, disc).to_json()})}


def edge_entry(edge: EdgeEvidence | None, hole: Hole) -> dict | None:
    """The painted grid's evidence of the hole as report.json lists it: the missing crossings, the
    grid's step and the slack (length unit), the ellipse between the missing and the tracked
    crossings (centre in the cup's frame) and the range of areas every consistent ellipse has
    (what the grid alone says of the area; searched from the fitted ``hole``, null where the search
    failed)."""
    if edge is None:
        return None
    bracket = edge.area_range([*hole.centre, *hole.axes, hole.angle])
    return {"missing_sites": int(len(edge.missing)), "step": float(edge.step), "slack": float(edge.slack),
            "ellipse": [float(v) for v in edge.ellipse], "area_range": None if bracket is None else list(bracket)}
