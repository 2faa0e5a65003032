"""Synthetic 3D sequences seen without correspondences: a block clamped at its left face (x = min)
and moved at its right face (x = max) by a rigid motion (stretch, shear, bend and twist),
optionally hiding a stiff or soft spherical inclusion at a random place, solved on a finer tet10
mesh (never the inversion's mesh) and seen in every frame as range clouds: the points where the
rays of one or more range cameras (orthographic, a regular grid of rays with a fresh random offset
every frame) first meet the deformed surface, with Gaussian noise along the ray (depth noise).
No point is seen twice and none carries an identity; the hidden motion stays available to
measure the correspondences a method recovers (:class:`examples.synthetic.clouds.HiddenMotion`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import jaxfem as jf

from refine.bundle.clouds import Clouds
from refine.bundle.experiment import Experiment, MeshDomain
from refine.bundle.io import Bundle
from refine.exceptions import ExperimentError
from examples.synthetic.clouds import HiddenMotion

#: the default block ``(x0, y0, z0, x1, y1, z1)``, mm
BLOCK = (0.0, 0.0, 0.0, 40.0, 20.0, 20.0)
#: the default camera: looking down and across, it sees the top, front (y = min) and right faces
VIEWS = ((-0.6, 0.5, -1.0),)


@dataclass(frozen=True)
class Sphere:
    """A spherical inclusion: centre ``(3,)`` and radius (mm), modulus ``ratio`` times the rest's."""

    centre: tuple
    radius: float
    ratio: float


@dataclass(frozen=True)
class SolidTruth:
    """What a synthetic 3D cloud sequence hides: an inclusion (or None) and the right face's rigid
    motion in the last frame, ``grip (6,)``: translation (mm), then rotation vector (radians,
    about the face's centre); frames see fractions of it."""

    inclusion: Sphere | None
    grip: tuple
    E: float = 83.76
    nu: float = 0.3


def random_solid_truth(rng: np.random.Generator, cause: str = "stiffer-region", block=BLOCK) -> SolidTruth:
    """A random grip motion (stretch 6-10 % of the length, shear 5-12 % of the height each way,
    turns up to 0.1 rad) and, unless ``cause`` is ``"none"``, a spherical inclusion of random place,
    radius (18-25 % of the smallest side) and ratio (``"stiffer-region"``: 4 to 10 times stiffer;
    ``"softer-region"``: 0.15 to 0.35) kept a radius and a tenth of the smallest side inside."""
    lo, hi = np.asarray(block[:3], float), np.asarray(block[3:], float)
    L = hi - lo
    sign = rng.choice([-1, 1], 2)
    grip = (float(rng.uniform(0.06, 0.1) * L[0]), *(float(s * rng.uniform(0.05, 0.12) * L[0]) for s in sign),
            *(float(v) for v in rng.uniform(-0.1, 0.1, 3)))
    if cause == "none":
        return SolidTruth(None, grip)
    if cause not in ("stiffer-region", "softer-region"):
        raise ExperimentError(f"unknown cause {cause!r} for a cloud sequence; use none, stiffer-region or "
                              "softer-region")
    r = rng.uniform(0.18, 0.25) * L.min()
    m = r + 0.1 * L.min()
    centre = tuple(float(v) for v in rng.uniform(lo + m, hi - m))
    ratio = rng.uniform(4, 10) if cause == "stiffer-region" else rng.uniform(0.15, 0.35)
    return SolidTruth(Sphere(centre, float(r), float(ratio)), grip)


def rigid(grip, s: float, centre):
    """The rigid map ``X (n, 3) -> x (n, 3)`` of fraction ``s`` of ``grip`` about ``centre``."""
    t, w = s * np.asarray(grip[:3]), s * np.asarray(grip[3:])
    a = np.linalg.norm(w)
    K = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
    R = np.eye(3) if a == 0 else np.eye(3) + np.sin(a) / a * K + (1 - np.cos(a)) / a ** 2 * K @ K
    return lambda X: (X - centre) @ R.T + centre + t


def solve_block(truth: SolidTruth, block, fractions, h: float) -> HiddenMotion:
    """The hidden motion: a tet10 box of element size ``h`` (mm), the inclusion as the cells whose
    centroid lies in the sphere, clamped left, the right face moved rigidly, frame by frame."""
    x0, y0, z0, x1, y1, z1 = block
    n = [max(1, int(round((b - a) / h))) for a, b in ((x0, x1), (y0, y1), (z0, z1))]
    mesh = jf.box(x0, y0, z0, x1, y1, z1, *n, element="tet10")
    left, right = mesh.side("left"), mesh.side("right")
    problem = jf.Problem(mesh, "neo-hookean", "solid", fixed=jf.dofs(mesh, np.concatenate([left, right])))
    solver = jf.Solver(problem)
    E = np.full(mesh.n_cells, truth.E)
    if truth.inclusion is not None:
        inc = truth.inclusion
        E[np.linalg.norm(mesh.centroids() - np.asarray(inc.centre), axis=1) <= inc.radius] *= inc.ratio
    centre = mesh.nodes[right].mean(axis=0)
    U, start = [], None
    on_right = np.zeros((mesh.n_nodes, 1), bool)
    on_right[right] = True
    for s in fractions:
        move = rigid(truth.grip, s, centre)
        theta = problem.params(E=E, nu=truth.nu, u_D=problem.prescribe(np.where(on_right, move(mesh.nodes) - mesh.nodes,
                                                                                0.0)))
        sol = solver.solve(theta, start=start)
        U.append(np.asarray(sol.u))
        start = (sol.u.reshape(-1), {"u_D": theta["u_D"], "f": theta["f"], "traction": theta["traction"]})
    return HiddenMotion(mesh, np.stack(U))


def range_cloud(mesh: jf.Mesh, x: np.ndarray, view, spacing: float, rng: np.random.Generator,
                noise: float = 0.0) -> np.ndarray:
    """Where the rays of an orthographic range camera first meet the surface of ``mesh`` at node
    positions ``x (n_nodes, 3)``: ``(n, 3)``, with Gaussian noise of ``noise`` (mm) along the ray.

    Args:
        view: the camera's viewing direction ``(3,)`` (from the camera to the body).
        spacing: distance between neighbouring rays (mm); the grid gets a random offset.
    """
    d = np.asarray(view, float) / np.linalg.norm(view)
    e1 = np.cross(d, [0.0, 0.0, 1.0] if abs(d[2]) < 0.9 else [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(d, e1)
    tri = x[mesh.boundary_facets()[:, :3]]  # corner triangles: the fine mesh's faces are small
    uv = np.stack([x @ e1, x @ e2], 1)
    lo, hi = uv.min(axis=0), uv.max(axis=0)
    a = np.arange(lo[0] + rng.uniform(0, spacing), hi[0], spacing)
    b = np.arange(lo[1] + rng.uniform(0, spacing), hi[1], spacing)
    A, B = np.meshgrid(a, b, indexing="ij")
    origins = A.reshape(-1, 1) * e1 + B.reshape(-1, 1) * e2 + (x @ d).min() * d - spacing * d
    hits = []
    for i in range(0, len(origins), 256):
        t = _first_hit(origins[i: i + 256], d, tri)
        o = origins[i: i + 256][np.isfinite(t)]
        hits.append(o + t[np.isfinite(t), None] * d)
    pts = np.concatenate(hits)
    return pts + rng.normal(0.0, noise, (len(pts), 1)) * d


def _first_hit(origins, d, tri) -> np.ndarray:
    """Distance along ``d`` from each origin ``(r, 3)`` to the first triangle ``(m, 3, 3)`` it meets
    (Moller-Trumbore), ``(r,)``; inf where it meets none."""
    p0, e1, e2 = tri[:, 0], tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    pv = np.cross(d, e2)  # (m, 3)
    det = np.einsum("md,md->m", e1, pv)
    ok = np.abs(det) > 1e-12
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = origins[:, None] - p0[None]  # (r, m, 3)
    u = np.einsum("rmd,md->rm", s, pv) * inv
    q = np.cross(s, e1[None])
    v = np.einsum("rmd,d->rm", q, d) * inv
    t = np.einsum("rmd,md->rm", q, e2) * inv
    hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
    return np.where(hit, t, np.inf).min(axis=1)


def solid_cloud_sequence(truth: SolidTruth, seed: int = 0, block=BLOCK, fractions=(0.25, 0.5, 0.75, 1.0),
                         h: float = 2.5, spacing: float = 1.0, noise: float = 0.02, views=VIEWS,
                         mesh_file: str = "domain.vtu",
                         name: str = "synthetic-range-clouds") -> tuple[Bundle, HiddenMotion]:
    """A bundle of range clouds only (frame 0 the reference) and the hidden motion that made it.

    Args:
        truth: the hidden inclusion and grip motion (:func:`random_solid_truth`).
        seed: seeds the rays' offsets and the noise.
        block: the block ``(x0, y0, z0, x1, y1, z1)`` (mm).
        fractions: the grip's motion in each frame as a fraction of ``truth.grip``.
        h: element size of the fine data-generating tet10 mesh (mm).
        spacing: distance between a camera's rays (mm).
        noise: standard deviation of the depth noise along each ray (mm).
        views: the cameras' viewing directions; a frame's cloud joins what each saw.
        mesh_file: the mesh file the bundle's domain names (the caller writes the model's mesh
            there: the data's fine mesh is not the model's).
    """
    rng = np.random.default_rng(seed)
    motion = solve_block(truth, block, fractions, h)
    mesh = motion.mesh
    frames = []
    for k in range(len(fractions) + 1):
        x = mesh.nodes + (0.0 if k == 0 else motion.displacements[k - 1])
        pts = np.concatenate([range_cloud(mesh, x, v, spacing, rng, noise) for v in views])
        frames.append(pts[rng.permutation(len(pts))])
    experiment = Experiment(name=name, kind="solid", domain=MeshDomain(mesh_file), law="neo-hookean", E=truth.E,
                            nu=truth.nu, units={"length": "mm", "stress": "kPa", "force": "mN"}, noise_std=noise)
    return Bundle(experiment, None, clouds=Clouds(tuple(frames))), motion
