"""A sheet with a hidden effect as a measurement bundle: the data of ``nonrigid demo`` (and of the 2D
tests and benchmarks).

The data never come from the discretisation that an inversion uses (no "inverse crime"): a larger
sheet is meshed with quadratic triangles whose edges follow the hidden inclusions and holes, pulled
from one side while the other is clamped; the tracked points are a grid inside a smaller region of
interest, their displacements are interpolated from that fine solution and Gaussian noise is added.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import jax
import numpy as np

import jaxfem as jf

from refine.bundle.io import Bundle
from refine.exceptions import ExperimentError
from refine.bundle.experiment import Experiment, RectangleDomain
from refine.bundle.observations import Forces, Observations

CAUSES = ("none", "stiffer-region", "softer-region", "hole", "two-regions", "rectangle")


@dataclass(frozen=True)
class Inclusion:
    """A hidden region: a ``jaxfem.Ellipse`` or ``jaxfem.Rect`` and its modulus ratio to the background."""

    shape: object
    ratio: float

    @property
    def cause(self) -> str:
        return "stiffer-region" if self.ratio > 1 else "softer-region"


@dataclass(frozen=True)
class Truth:
    """What a synthetic bundle hides: inclusions, holes, and the sheet's material law ``law``
    with its extra parameters ``parameters`` (e.g. a fibre-reinforced sheet's ``fibre_angle``;
    the bundle's initial model stays neo-Hookean, as a modeller who assumed isotropy would write)."""

    inclusions: tuple = ()
    holes: tuple = ()
    E: float = 83.76
    nu: float = 0.3
    thickness: float = 1.0
    notes: dict = field(default_factory=dict)
    law: str = "neo-hookean"
    parameters: dict = field(default_factory=dict)

    @property
    def causes(self) -> list[str]:
        return [i.cause for i in self.inclusions] + ["hole"] * len(self.holes)


def random_truth(rng: np.random.Generator, cause: str, roi=(20.0, 10.0, 120.0, 70.0)) -> Truth:
    """Draw a hidden effect of the given kind at a random place, size and ratio inside ``roi``.

    ``cause`` is one of :data:`CAUSES`. Shapes keep a margin from the ROI's edges of about a
    sixth of its height, so the driving boundary does not cut through them.
    """
    x0, y0, x1, y1 = roi
    W, H = x1 - x0, y1 - y0
    m = H / 6

    def place(r):
        return rng.uniform(x0 + m + r, x1 - m - r), rng.uniform(y0 + m + r, y1 - m - r)

    def ellipse(rmin, rmax):
        a, b = rng.uniform(rmin, rmax, 2)
        cx, cy = place(max(a, b))
        return jf.Ellipse(cx, cy, a, b, rng.uniform(0, np.pi))

    if cause == "none":
        return Truth()
    if cause == "stiffer-region":
        r = rng.uniform(0.1, 0.16) * H
        cx, cy = place(r)
        return Truth(inclusions=(Inclusion(jf.Ellipse(cx, cy, r, r), float(rng.uniform(3, 10))),))
    if cause == "softer-region":
        return Truth(inclusions=(Inclusion(ellipse(0.1 * H, 0.2 * H), float(rng.uniform(0.15, 0.4))),))
    if cause == "hole":
        return Truth(holes=(ellipse(0.08 * H, 0.15 * H),))
    if cause == "two-regions":
        while True:
            a, b = ellipse(0.09 * H, 0.13 * H), ellipse(0.09 * H, 0.13 * H)
            if np.hypot(a.cx - b.cx, a.cy - b.cy) > 0.35 * W:
                break
        return Truth(inclusions=(Inclusion(a, float(rng.uniform(3, 8))), Inclusion(b, float(rng.uniform(0.2, 0.4)))))
    if cause == "rectangle":  # like the paper's embedded rectangle (Section 3.1), ratio ~10
        w, h = rng.uniform(0.15, 0.25) * W, rng.uniform(0.2, 0.35) * H
        cx, cy = place(max(w, h) / 2)
        return Truth(inclusions=(Inclusion(jf.Rect(cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2), 10.0),))
    raise ExperimentError(f"unknown cause {cause!r}; use one of {', '.join(CAUSES)}")


def with_fibres(rng: np.random.Generator, truth: Truth, stiffness=(2.0, 6.0)) -> Truth:
    """``truth`` in a fibre-reinforced sheet (``jaxfem`` law ``fibre-reinforced``, one family):
    the fibre angle drawn in 20-70 degrees from the pull on either side (radians in
    ``parameters``; fibres along or across the pull change little more than the contraction), the
    fibres' stiffness over the matrix's uniform in ``stiffness``."""
    angle = float(rng.choice([-1.0, 1.0]) * np.deg2rad(rng.uniform(20.0, 70.0)))
    return replace(truth, law="fibre-reinforced",
                   parameters={"fibre_angle": angle, "fibre_stiffness": float(rng.uniform(*stiffness))})


def _fine_solution(truth: Truth, sheet, pull: float, fractions, h: float, force_roi=None):
    """Solve the pulled sheet at each load fraction on a conforming quadratic mesh; with
    ``force_roi``, also return the force crossing its right side in each frame, ``(n_frames, 2)``."""
    X0, Y0, X1, Y1 = sheet
    mesh = jf.plate(X0, Y0, X1, Y1, h, holes=list(truth.holes), inclusions=[i.shape for i in truth.inclusions],
                    element="tri6")
    left, right = mesh.side("left"), mesh.side("right")
    fixed = np.concatenate([jf.dofs(mesh, left), jf.dofs(mesh, right)])
    problem = jf.Problem(mesh, truth.law, "plane-stress", fixed=fixed)
    solver = jf.Solver(problem)
    section = None if force_roi is None else _section_force(solver, mesh, force_roi, truth.thickness)
    E = np.full(mesh.n_cells, truth.E)
    for k, inc in enumerate(truth.inclusions, start=1):
        E[mesh.regions == k] = truth.E * inc.ratio
    U, forces, start = [], [], None
    for s in fractions:
        target = problem.prescribe(lambda X: np.stack([np.where(X[:, 0] > X0 + 0.5 * (X1 - X0),
                                                                s * pull * (X1 - X0), 0.0), 0 * X[:, 1]], 1))
        theta = problem.params(E=E, nu=truth.nu, thickness=truth.thickness, u_D=target, **truth.parameters)
        sol = solver.solve(theta, start=start)
        U.append(np.asarray(sol.u))
        forces.append(section(sol.u, theta) if section else np.full(2, np.nan))
        start = (sol.u.reshape(-1), {"u_D": theta["u_D"], "f": theta["f"], "traction": theta["traction"]})
    return mesh, U, np.array(forces)


def _section_force(solver, mesh, roi, thickness: float, per_h: int = 8):
    """The force that crosses the ROI's right side ``x = roi[2], roi[1] <= y <= roi[3]``, as a
    function ``(u, theta) -> (2,)``: the traction P e_x of the first Piola stress integrated along
    the segment (midpoint rule, ``per_h`` points per element; P is the cell average, which on a
    full section reproduces the clamp's reaction to ~1e-4). The clamp's reaction itself would be
    the force through the whole sheet, wider than the ROI, which no model of the ROI can predict."""
    from jaxfem.postprocess import first_piola_stress

    x1, y0, y1 = roi[2], roi[1], roi[3]
    h = float(np.sqrt(np.median(mesh.volumes())))
    n = max(16, int(np.ceil(per_h * (y1 - y0) / h)))
    ys = y0 + (y1 - y0) * (np.arange(n) + 0.5) / n
    cells = jf.locate(mesh, np.stack([np.full(n, x1), ys], 1)).cells
    # one compiled function: called eagerly, every jax op would compile on its own
    stress = jax.jit(lambda u, theta: first_piola_stress(solver, u, theta)[:, :2, 0])

    def force(u, theta) -> np.ndarray:
        return thickness * (y1 - y0) / n * np.asarray(stress(u, theta))[cells].sum(axis=0)

    return force


def grid_points(roi, spacing: float) -> np.ndarray:
    """A regular grid of points covering ``roi`` (its edges included), ``(n, 2)``."""
    x0, y0, x1, y1 = roi
    xs = np.linspace(x0, x1, int(round((x1 - x0) / spacing)) + 1)
    ys = np.linspace(y0, y1, int(round((y1 - y0) / spacing)) + 1)
    X, Y = np.meshgrid(xs, ys)
    return np.stack([X.ravel(), Y.ravel()], 1)


def synthetic_bundle(truth: Truth, seed: int = 0, roi=(20.0, 10.0, 120.0, 70.0), sheet=(0.0, 0.0, 140.0, 80.0),
                     spacing: float = 5.0, noise: float = 0.02, pull: float = 0.15,
                     fractions=(0.25, 0.5, 0.75, 1.0), h: float = 2.0, validate_fraction: float = 0.2,
                     forces: bool = False, name: str = "synthetic") -> Bundle:
    """Generate a measurement bundle of a sheet hiding ``truth``.

    Args:
        truth: the hidden effect (see :func:`random_truth`).
        seed: seeds the noise and the choice of validation points.
        roi: tracked region ``[xmin, ymin, xmax, ymax]`` (the bundle's domain), mm.
        sheet: the larger physical sheet, clamped at its left edge and pulled at its right edge.
        spacing: grid spacing of the tracked points, mm.
        noise: standard deviation of the Gaussian noise on each displacement component, mm.
        pull: final stretch of the sheet (0.15 = 15 %); frames at ``fractions`` of it.
        h: element size of the fine data-generating mesh (quadratic triangles), mm.
        validate_fraction: share of interior points held out for validation.
        forces: write the measured force crossing the ROI's right side (makes moduli absolute).
    """
    rng = np.random.default_rng(seed)
    mesh, U, F = _fine_solution(truth, sheet, pull, fractions, h, roi if forces else None)
    pts = grid_points(roi, spacing)
    inside_hole = np.zeros(len(pts), bool)
    for hole in truth.holes:
        inside_hole |= hole.contains(pts) | (np.linalg.norm(pts - hole.to_curve(pts), axis=1) < 0.3 * spacing)
    pts = pts[~inside_hole]  # no paint on a hole
    probe = jf.locate(mesh, pts)
    disp = np.stack([np.asarray(probe(u)) for u in U]) + rng.normal(0.0, noise, (len(U), len(pts), 2))
    x0, y0, x1, y1 = roi
    tol = 1e-6 * spacing
    on_edge = ((np.abs(pts[:, 0] - x0) < tol) | (np.abs(pts[:, 0] - x1) < tol)
               | (np.abs(pts[:, 1] - y0) < tol) | (np.abs(pts[:, 1] - y1) < tol))
    roles = np.where(on_edge, "boundary", "guide").astype(object)
    interior = np.flatnonzero(~on_edge)
    held = rng.choice(interior, int(round(validate_fraction * len(interior))), replace=False)
    roles[held] = "validate"
    experiment = Experiment(name=name, kind="plane-stress", domain=RectangleDomain(*roi), law="neo-hookean",
                            E=truth.E, nu=truth.nu, thickness=truth.thickness,
                            units={"length": "mm", "stress": "kPa", "force": "mN"},
                            noise_std=noise if noise > 0 else None)
    obs = Observations(ids=np.arange(1, len(pts) + 1), reference=pts, roles=np.asarray(roles, str),
                       displacements=disp,
                       forces=Forces(("right",), F[:, None, :]) if forces else None)
    return Bundle(experiment, obs)
