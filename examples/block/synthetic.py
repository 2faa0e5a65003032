"""Synthetic 3D block bundles with a hidden ellipsoidal inclusion (issue 23's "stiff inclusion in a
block"): a neo-Hookean block held by two grips, the left one (x = min) fixed, the right one
(x = max) pulled or pushed along x, hiding a stiffer or softer ellipsoid of random place, semi-axes,
orientation and modulus ratio drawn under a seed (or none). The data come from an independent solve
on a finer ``tet10`` mesh than the inversion's (a cell is of the inclusion's material where most
of its sample points lie inside the ellipsoid: sharp, as a voxel model's phases), with Gaussian
noise on every displacement.

Points (lengths in mm, moduli in kPa), all on the block's surface:

- the two gripped end faces (``left``, ``right``): a square grid of pitch ``spacing``, role
  ``boundary`` (markers on the grips' jaws, which move with the faces they clamp: what drives the
  model);
- the faces a scanner sees (``faces``, jaxfem's names: ``bottom``/``top`` are y = min/max,
  ``back``/``front`` z = min/max): a square grid of pitch ``spacing`` with a random offset along
  x, at least half a pitch from the grips, ``guide`` or ``validate`` (one in three).

No interior marker: :class:`refine.model.MeasuredModel` compares a solid's points with the model
on its surface (it places every point there), and a scanner sees only the surface. The model mesh
written beside the bundle (``mesh.vtu``) is a sound block at ``h_model``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

import jaxfem as jf
from jaxfem.graded import graded_box, graded_ticks

from refine.bundle.experiment import Experiment, MeshDomain
from refine.bundle.io import Bundle, write_bundle
from refine.bundle.observations import Observations
from refine.exceptions import ExperimentError
from refine.solid.inclusion_mesh import extent

CAUSES = ("stiffer-region", "softer-region", "none")
"""What a synthetic block may hide."""


@dataclass(frozen=True)
class Ellipsoid:
    """An ellipsoidal inclusion: ``centre (3,)`` and ``axes (3,)`` (semi-axes, mm) along the columns
    of ``rotation (3, 3)``; its modulus is ``ratio`` times the rest's."""

    centre: tuple
    axes: tuple
    rotation: tuple
    ratio: float

    def inside(self, X) -> np.ndarray:
        """``(n,)`` bool: whether the points ``X (n, 3)`` lie in the ellipsoid."""
        local = (np.asarray(X, float) - np.asarray(self.centre)) @ np.asarray(self.rotation)
        return ((local / np.asarray(self.axes)) ** 2).sum(axis=1) <= 1.0

    @property
    def volume(self) -> float:
        """Its volume (mm^3)."""
        return float(4.0 / 3.0 * np.pi * np.prod(self.axes))


@dataclass(frozen=True)
class BlockSetting:
    """A synthetic block experiment: the ``block`` ``(x0, y0, z0, x1, y1, z1)`` (mm), the right grip's
    motion along x per frame (mm, negative: compression), the material (``E`` kPa, ``nu``), the
    data's and the model's ``tet10`` element sizes (mm, ``h_data < h_model``; the data at 2 mm, finer
    than the 2.5 mm the diagnosis refits an inclusion on, :mod:`refine.solid.inclusion_mesh`), the
    grid ``spacing`` (mm), the ``noise`` std of each displacement component (mm) and the ``faces``
    seen. ``h_data_inclusion`` (mm, None: uniform ``h_data``): the data's element size over the
    inclusion's bounding box (one ``h_data`` wider), graded to ``h_data`` away from it. The data
    give each cell the inclusion's modulus where half its samples lie inside
    (:func:`inclusion_fraction`), so their inclusion is a staircase: at 2 mm its volume is 1-3.5 %
    short of the ellipsoid's on the benchmark's seeds, graded to 1 mm over it 0.06-0.56 %."""

    block: tuple = (0.0, 0.0, 0.0, 40.0, 20.0, 20.0)
    grip: tuple = (1.6, 3.2)
    E: float = 50.0
    nu: float = 0.3
    h_data: float = 2.0
    h_model: float = 4.0
    h_data_inclusion: float | None = None
    spacing: float = 2.5
    noise: float = 0.01
    faces: tuple = field(default=("top", "front", "bottom", "back"))


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    """A rotation ``(3, 3)`` drawn uniformly (QR of a Gaussian matrix, signs fixed)."""
    q, r = np.linalg.qr(rng.standard_normal((3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def random_inclusion(rng: np.random.Generator, block, cause: str = "stiffer-region") -> Ellipsoid | None:
    """An ellipsoid drawn under ``rng`` (None for ``cause`` ``"none"``): semi-axes 22-32 % of the
    block's smallest side, any orientation, its centre leaving a tenth of that side between the
    ellipsoid's bounding sphere and every face; ratio 2 to 5 (``"stiffer-region"``) or 0.2 to 0.5
    (``"softer-region"``). Seen from the surface alone, a much stiffer inclusion acts as a rigid
    one of a smaller volume: a 7 times stiffer one was fitted at the ratio's bound (148) with 53 %
    of its volume, which the model fitted better than the truth (so ratios drawn here stay below 5)."""
    if cause not in CAUSES:
        raise ExperimentError(f"unknown cause {cause!r} for a synthetic block; use one of {', '.join(CAUSES)}")
    if cause == "none":
        return None
    lo, hi = np.asarray(block[:3], float), np.asarray(block[3:], float)
    small = (hi - lo).min()
    axes = rng.uniform(0.22, 0.32, 3) * small
    margin = axes.max() + 0.1 * small
    centre = rng.uniform(lo + margin, hi - margin)
    ratio = rng.uniform(2.0, 5.0) if cause == "stiffer-region" else rng.uniform(0.2, 0.5)
    R = random_rotation(rng)
    return Ellipsoid(tuple(map(float, centre)), tuple(map(float, axes)), tuple(tuple(map(float, r)) for r in R),
                     float(ratio))


def inclusion_fraction(mesh: jf.Mesh, inclusion: Ellipsoid | None, samples: int = 5) -> np.ndarray:
    """``(n_cells,)``: the fraction of each cell's sample points inside ``inclusion`` (zeros for
    None). The samples are the 56 points of a lattice of ``samples`` steps per edge of each cell's
    corner tetrahedron (barycentric coordinates ``(i, j, k, l) / samples``, faces included)."""
    if inclusion is None:
        return np.zeros(mesh.n_cells)
    n = samples
    lam = np.array([(i, j, k, n - i - j - k) for i in range(n + 1) for j in range(n + 1 - i)
                    for k in range(n + 1 - i - j)], float) / n
    pts = np.einsum("qc,ncd->nqd", lam, mesh.nodes[mesh.cells[:, :4]])
    return inclusion.inside(pts.reshape(-1, 3)).reshape(mesh.n_cells, -1).mean(axis=1)


def _grid(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.stack(np.meshgrid(a, b, indexing="ij"), -1).reshape(-1, 2)


def block_points(s: BlockSetting, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Reference positions ``(n, 3)`` and roles ``(n,)`` of the tracked points (see the module)."""
    lo, hi = np.asarray(s.block[:3], float), np.asarray(s.block[3:], float)
    axis = lambda d, off=0.0: np.arange(lo[d] + off, hi[d] + 1e-9, s.spacing)  # noqa: E731
    ends = [np.c_[np.full(len(g), x), g] for x in (lo[0], hi[0]) for g in [_grid(axis(1), axis(2))]]
    along = axis(0, 0.5 * s.spacing + rng.uniform(0, 0.5) * s.spacing)
    along = along[(along > lo[0] + 0.5 * s.spacing) & (along < hi[0] - 0.5 * s.spacing)]
    sides = {"bottom": (1, lo[1]), "top": (1, hi[1]), "back": (2, lo[2]), "front": (2, hi[2])}
    seen = []
    for name in s.faces:
        if name not in sides:
            raise ExperimentError(f"unknown face {name!r}; a block's seen faces are {', '.join(sides)}")
        d, value = sides[name]
        other = 3 - d  # the third axis (1 + 2 = 3)
        g = _grid(along, axis(other))
        P = np.empty((len(g), 3))
        P[:, 0], P[:, d], P[:, other] = g[:, 0], value, g[:, 1]
        seen.append(P)
    seen = np.unique(np.round(np.concatenate(seen), 9), axis=0)  # an edge two faces share, once
    roles = np.where(rng.uniform(size=len(seen)) < 1 / 3, "validate", "guide")
    X = np.vstack([*ends, seen])
    return X, np.r_[np.full(len(X) - len(seen), "boundary"), roles]


def data_mesh(s: BlockSetting, inclusion: Ellipsoid | None) -> jf.Mesh:
    """The data's ``tet10`` mesh of the block: ``s.h_data`` everywhere, or ``s.h_data_inclusion``
    over ``inclusion``'s bounding box widened by ``s.h_data``, graded to ``s.h_data`` away from it
    (:func:`jaxfem.graded.graded_ticks`)."""
    x0, y0, z0, x1, y1, z1 = s.block
    if s.h_data_inclusion is None or inclusion is None:
        n = [max(1, int(round((b - a) / s.h_data))) for a, b in ((x0, x1), (y0, y1), (z0, z1))]
        return jf.box(x0, y0, z0, x1, y1, z1, *n, element="tet10")
    a, b = extent(inclusion.centre, inclusion.axes, inclusion.rotation)
    return graded_box(tuple(graded_ticks(lo, hi, (a[d] - s.h_data, b[d] + s.h_data), s.h_data_inclusion, s.h_data)
                            for d, (lo, hi) in enumerate(((x0, x1), (y0, y1), (z0, z1)))))


def data_inclusion(s: BlockSetting, inclusion: Ellipsoid | None) -> tuple[jf.Mesh, np.ndarray]:
    """The data's mesh and which of its cells take the inclusion's modulus (``(n_cells,)`` bool)."""
    mesh = data_mesh(s, inclusion)
    return mesh, inclusion_fraction(mesh, inclusion) >= 0.5


def solve_data(s: BlockSetting, inclusion: Ellipsoid | None, points) -> np.ndarray:
    """Displacements ``(frames, n, 3)`` at ``points (n, 3)`` of the block with ``inclusion`` meshed
    with ``tet10`` (:func:`data_mesh`), left face fixed, right face moved by each of ``s.grip``."""
    mesh, inside = data_inclusion(s, inclusion)
    right = mesh.side("right")
    problem = jf.Problem(mesh, "neo-hookean", "solid", fixed=jf.dofs(mesh, np.r_[mesh.side("left"), right]))
    solver = jf.Solver(problem)
    ratio = 1.0 if inclusion is None else inclusion.ratio
    E = s.E * np.where(inside, ratio, 1.0)
    probe = jf.locate(mesh, points, tol=1e-6)
    out, start = [], None
    for g in s.grip:
        U = np.zeros((mesh.n_nodes, 3))
        U[right, 0] = g
        theta = problem.params(E=E, nu=s.nu, u_D=problem.prescribe(U))
        sol = solver.solve(theta, start=start)
        start = (sol.u.reshape(-1), {"u_D": theta["u_D"], "f": theta["f"], "traction": theta["traction"]})
        out.append(np.asarray(probe(sol.u)))
    return np.stack(out)


def model_mesh(s: BlockSetting) -> jf.Mesh:
    """The inversion's mesh: the sound block, ``tet10`` at ``s.h_model``."""
    x0, y0, z0, x1, y1, z1 = s.block
    n = [max(1, int(round((b - a) / s.h_model))) for a, b in ((x0, x1), (y0, y1), (z0, z1))]
    return jf.box(x0, y0, z0, x1, y1, z1, *n, element="tet10")


def block_bundle(cause: str = "stiffer-region", seed: int = 0, setting: BlockSetting = BlockSetting(),
                 inclusion: Ellipsoid | None = None) -> tuple[Bundle, jf.Mesh, Ellipsoid | None]:
    """A block bundle (see the module), its model mesh and the hidden inclusion.

    Args:
        cause: what it hides (:data:`CAUSES`), drawn by :func:`random_inclusion` under ``seed``
            unless ``inclusion`` gives it.
        seed: seeds the inclusion, the grid's offset, the roles and the noise.
        setting: the experiment (:class:`BlockSetting`).
    """
    if setting.h_data >= setting.h_model:
        raise ExperimentError(f"the data's mesh (h_data = {setting.h_data}) must be finer than the model's "
                              f"(h_model = {setting.h_model}): equal meshes would hide the discretisation error")
    rng = np.random.default_rng(seed)
    truth = inclusion if inclusion is not None else random_inclusion(rng, setting.block, cause)
    X, roles = block_points(setting, rng)
    U = solve_data(setting, truth, X) + rng.normal(0.0, setting.noise, (len(setting.grip), *X.shape))
    obs = Observations(np.arange(1, len(X) + 1), X, roles, U)
    exp = Experiment(name="block", kind="solid", domain=MeshDomain("mesh.vtu"), law="neo-hookean", E=setting.E,
                     nu=setting.nu, units={"length": "mm", "stress": "kPa", "force": "mN"}, noise_std=setting.noise)
    return Bundle(exp, obs), model_mesh(setting), truth


def write_block_bundle(root: str | Path, **kw) -> tuple[Path, Ellipsoid | None]:
    """:func:`block_bundle` written to the directory ``root`` (with ``mesh.vtu``); returns it and the
    hidden inclusion."""
    bundle, mesh, truth = block_bundle(**kw)
    root = Path(root)
    root.mkdir(parents=True, exist_ok=True)
    jf.write_vtu(root / "mesh.vtu", mesh)
    return write_bundle(root, bundle), truth
