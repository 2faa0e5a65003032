"""Synthetic sequences seen without correspondences: a sheet clamped at its left side and moved at
its right side by a rigid motion (stretch, shear and turn), hiding a stiff or soft inclusion,
solved on a finer quadratic mesh that follows the inclusion (never the inversion's mesh), and
seen in every frame only as unlabelled samples of its outline and of its surface, with noise.
Fresh samples in every frame: no point is seen twice. The hidden motion stays available to
measure the correspondences a method recovers.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import jaxfem as jf

from refine.bundle.clouds import Clouds
from refine.bundle.experiment import Experiment, RectangleDomain
from refine.bundle.io import Bundle
from refine.exceptions import ExperimentError
from refine.demo_data import Inclusion


@dataclass(frozen=True)
class GripMotion:
    """The right grip's rigid motion in the last frame: translation ``(tx, ty)`` (length) and
    rotation ``angle`` (radians, about the grip's centre); frames see fractions of it."""

    tx: float
    ty: float
    angle: float


@dataclass(frozen=True)
class CloudTruth:
    """What a synthetic cloud sequence hides: an inclusion (or None) and the grip's motion."""

    inclusion: Inclusion | None
    grip: GripMotion
    E: float = 83.76
    nu: float = 0.3


def random_cloud_truth(rng: np.random.Generator, cause: str = "stiffer-region",
                       domain=(0.0, 0.0, 100.0, 50.0)) -> CloudTruth:
    """A random grip motion and, unless ``cause`` is ``"none"``, a circular inclusion of random
    place, size and ratio (``"stiffer-region"``: 4 to 10 times stiffer; ``"softer-region"``: 0.15
    to 0.35) kept a fifth of the height away from every side."""
    x0, y0, x1, y1 = domain
    W, H = x1 - x0, y1 - y0
    grip = GripMotion(float(rng.uniform(0.08, 0.14) * W), float(rng.choice([-1, 1]) * rng.uniform(0.1, 0.2) * H),
                      float(rng.uniform(-0.12, 0.12)))
    if cause == "none":
        return CloudTruth(None, grip)
    if cause not in ("stiffer-region", "softer-region"):
        raise ExperimentError(f"unknown cause {cause!r} for a cloud sequence; use none, stiffer-region or "
                              "softer-region")
    r = rng.uniform(0.16, 0.22) * H
    m = 0.2 * H + r
    centre = (rng.uniform(x0 + m, x1 - m), rng.uniform(y0 + m, y1 - m))
    ratio = rng.uniform(4, 10) if cause == "stiffer-region" else rng.uniform(0.15, 0.35)
    return CloudTruth(Inclusion(jf.Ellipse(*centre, r, r), float(ratio)), grip)


@dataclass(frozen=True, eq=False)
class HiddenMotion:
    """The fine solution of a synthetic sequence: ask it where material points went.

    Attributes:
        mesh: the fine quadratic mesh; displacements ``(n_frames, n_nodes, 2)``, frames 1..n.
    """

    mesh: jf.Mesh
    displacements: np.ndarray

    def positions(self, X) -> np.ndarray:
        """Positions of the material points ``X (n, 2)`` (reference coordinates) in frames 0..n,
        ``(n_frames + 1, n, 2)``."""
        probe = jf.locate(self.mesh, np.asarray(X, float), tol=1e-6)
        moved = [np.asarray(probe(u)) for u in self.displacements]
        return np.asarray(X, float)[None] + np.concatenate([np.zeros((1, *np.shape(X))), np.stack(moved)])


def _solve(truth: CloudTruth, domain, fractions, h: float) -> HiddenMotion:
    x0, y0, x1, y1 = domain
    inclusions = [] if truth.inclusion is None else [truth.inclusion.shape]
    mesh = jf.plate(x0, y0, x1, y1, h, inclusions=inclusions, element="tri6")
    left, right = mesh.side("left"), mesh.side("right")
    problem = jf.Problem(mesh, "neo-hookean", "plane-stress", fixed=jf.dofs(mesh, np.concatenate([left, right])))
    solver = jf.Solver(problem)
    E = np.full(mesh.n_cells, truth.E)
    if truth.inclusion is not None:
        E[mesh.regions == 1] = truth.E * truth.inclusion.ratio
    centre = np.array([x1, 0.5 * (y0 + y1)])
    U, start = [], None
    for s in fractions:
        g = truth.grip
        c, sn = np.cos(s * g.angle), np.sin(s * g.angle)

        def grip(X):
            d = X - centre
            moved = np.stack([c * d[:, 0] - sn * d[:, 1], sn * d[:, 0] + c * d[:, 1]], 1) + centre
            u = moved + s * np.array([g.tx, g.ty]) - X
            return np.where(np.abs(X[:, :1] - x1) < 1e-9 * (x1 - x0), u, 0.0)

        theta = problem.params(E=E, nu=truth.nu, thickness=1.0, u_D=problem.prescribe(grip))
        sol = solver.solve(theta, start=start)
        U.append(np.asarray(sol.u))
        start = (sol.u.reshape(-1), {"u_D": theta["u_D"], "f": theta["f"], "traction": theta["traction"]})
    return HiddenMotion(mesh, np.stack(U))


def outline_samples(rng: np.random.Generator, domain, n: int) -> np.ndarray:
    """``n`` points drawn uniformly along the rectangle's perimeter, ``(n, 2)``."""
    x0, y0, x1, y1 = domain
    W, H = x1 - x0, y1 - y0
    t = rng.uniform(0, 2 * (W + H), n)
    pts = np.empty((n, 2))
    for lo, hi, f in ((0, W, lambda s: (x0 + s, y0)), (W, W + H, lambda s: (x1, y0 + s)),
                      (W + H, 2 * W + H, lambda s: (x1 - s, y1)), (2 * W + H, 2 * (W + H), lambda s: (x0, y1 - s))):
        on = (t >= lo) & (t < hi)
        px, py = f(t[on] - lo)
        pts[on, 0], pts[on, 1] = px, py
    return pts


def cloud_sequence(truth: CloudTruth, seed: int = 0, domain=(0.0, 0.0, 100.0, 50.0),
                   fractions=(0.2, 0.4, 0.6, 0.8, 1.0), h: float = 2.0, outline_spacing: float = 1.0,
                   surface_density: float = 0.02, noise: float = 0.05,
                   name: str = "synthetic-clouds") -> tuple[Bundle, HiddenMotion]:
    """A bundle of clouds only (frame 0 the reference) and the hidden motion that made it.

    Args:
        truth: the hidden inclusion and grip motion (:func:`random_cloud_truth`).
        seed: seeds the samples and the noise.
        domain: the sheet ``[xmin, ymin, xmax, ymax]`` (mm), the bundle's domain.
        fractions: the grip's motion in each frame as a fraction of ``truth.grip``.
        h: element size of the fine data-generating mesh (quadratic triangles), mm.
        outline_spacing: mean distance between outline samples, mm.
        surface_density: surface samples per mm^2.
        noise: standard deviation of each coordinate's Gaussian noise, mm.
    """
    rng = np.random.default_rng(seed)
    motion = _solve(truth, domain, fractions, h)
    x0, y0, x1, y1 = domain
    n_out = int(round(2 * ((x1 - x0) + (y1 - y0)) / outline_spacing))
    n_surf = int(round(surface_density * (x1 - x0) * (y1 - y0)))
    frames = []
    for k in range(len(fractions) + 1):
        X = np.concatenate([outline_samples(rng, domain, n_out),
                            np.stack([rng.uniform(x0, x1, n_surf), rng.uniform(y0, y1, n_surf)], 1)])
        x = motion.positions(X)[k] + rng.normal(0.0, noise, X.shape)
        frames.append(x[rng.permutation(len(x))])  # no order to give identities away
    experiment = Experiment(name=name, kind="plane-stress", domain=RectangleDomain(*domain), law="neo-hookean",
                            E=truth.E, nu=truth.nu, thickness=1.0,
                            units={"length": "mm", "stress": "kPa", "force": "mN"}, noise_std=noise)
    return Bundle(experiment, None, clouds=Clouds(tuple(frames))), motion
