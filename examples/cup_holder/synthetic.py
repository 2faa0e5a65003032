"""Synthetic 3D cup-holder bundles (the paper's Sec. 4): a cup holder with a hidden elliptic hole
through its bottom (or none), squeezed by a uniform pressure on its bottom's outer face with the rim
held, solved on a finer ``tet10`` mesh than the inversion uses and sampled with noise where a
structured-light camera below sees it.

Points (lengths in mm, forces in N, moduli in MPa):

- the bottom's outer face (z = 0): the crossings of a painted square grid of pitch ``spacing``
  turned by a random angle, those on material (none inside the hole); ``boundary`` in the outer
  ring ``r >= r_in - spacing / 2`` (under the wall), else ``guide`` or ``validate`` (one in three);
- the outer wall: rings at four heights, ``validate`` (the global model's held-out check);
- the rim (z = height), held by the fixture: three rings of pitch ``spacing``, ``boundary`` (what
  holds the global model).

Each frame's total force is in ``forces.csv`` on the side ``back`` (the z = 0 face). The model
mesh (``mesh.vtu``) is the cup holder without a hole at ``h_model``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

import jaxfem as jf
from examples.cup_holder import cup_holder

from refine.bundle.experiment import Experiment, MeshDomain
from refine.bundle.io import Bundle, write_bundle
from refine.bundle.observations import Forces, Observations


@dataclass(frozen=True)
class CupGeometry:
    """A cup holder's inner and outer radius, height and bottom thickness (mm), its material
    (E in MPa; a foam-like neo-Hookean solid)."""

    r_in: float = 8.0
    r_out: float = 11.0
    height: float = 8.0
    bottom: float = 3.0
    E: float = 1.0
    nu: float = 0.4
    law: str = "neo-hookean"

    @property
    def diameter(self) -> float:
        """The bottom's diameter (mm): the paper's scale for the centre error."""
        return 2 * self.r_out


def random_hole(geometry: CupGeometry, seed: int) -> jf.Ellipse:
    """An elliptic hole inside the floor drawn under ``seed``: semi-axes 1.8-3.2 and 1.2-2.4 mm
    (scaled with ``r_in / 8``), any orientation, centre anywhere leaving 1.2 mm to the inner wall."""
    rng = np.random.default_rng(seed)
    k = geometry.r_in / 8.0
    rx, ry = k * rng.uniform(1.8, 3.2), k * rng.uniform(1.2, 2.4)
    r, phi = rng.uniform(0.0, geometry.r_in - max(rx, ry) - 1.2 * k), rng.uniform(0, 2 * np.pi)
    return jf.Ellipse(r * np.cos(phi), r * np.sin(phi), rx, ry, rng.uniform(0, np.pi))


def _points(g: CupGeometry, hole, spacing: float, rng) -> tuple[np.ndarray, np.ndarray]:
    """Reference positions ``(n, 3)`` and roles ``(n,)`` (see the module)."""
    t = rng.uniform(0, np.pi / 2)
    k = np.arange(-int(g.r_out / spacing) - 1, int(g.r_out / spacing) + 2) * spacing
    grid = np.stack(np.meshgrid(k, k), -1).reshape(-1, 2) + rng.uniform(-0.5, 0.5, 2) * spacing
    grid = grid @ np.array([[np.cos(t), np.sin(t)], [-np.sin(t), np.cos(t)]])
    r = np.hypot(*grid.T)
    keep = r < g.r_out - 0.25 * spacing
    if hole is not None:  # material only, and not on the hole's very edge (a crossing there is lost)
        edge = np.linalg.norm(grid - hole.to_curve(grid), axis=1)
        keep &= ~hole.contains(grid) & (edge > 0.1 * spacing)
    grid, r = grid[keep], r[keep]
    inner = r < g.r_in - 0.5 * spacing
    bottom_roles = np.where(inner, np.where(rng.uniform(size=len(r)) < 1 / 3, "validate", "guide"), "boundary")
    ring = lambda radius, z, n: np.c_[radius * np.cos(np.linspace(0, 2 * np.pi, n + 1)[:-1] + z),  # noqa: E731
                                      radius * np.sin(np.linspace(0, 2 * np.pi, n + 1)[:-1] + z), np.full(n, z)]
    n_ring = max(12, int(2 * np.pi * g.r_out / (2 * spacing)))
    wall = np.vstack([ring(g.r_out, z, n_ring) for z in np.linspace(0, g.height, 6)[1:-1]])
    radii = g.r_in + np.array([0.1, 0.5, 0.9]) * (g.r_out - g.r_in)
    rim = np.vstack([ring(r, g.height, max(12, int(2 * np.pi * r / spacing))) for r in radii])
    X = np.vstack([np.c_[grid, np.zeros(len(grid))], wall, rim])
    roles = np.r_[bottom_roles, np.full(len(wall), "validate"), np.full(len(rim), "boundary")]
    return X, roles


def data_hole_h(hole, h: float) -> float | None:
    """The data's element size along ``hole``'s curve: ``min(h / 4, 0.2 b^2 / a)`` (b^2 / a: the
    ellipse's smallest radius of curvature), None without a hole.

    A mesh cuts a hole as the polygon through its curve's nodes, smaller than the ellipse: with
    the data's mesh size along the curve the data's hole keeps a few percent less area than the
    drawn ellipse, so the data's object is not the one its truth names; at this size the polygon
    keeps nearly all of it."""
    if hole is None:
        return None
    return min(h / 4, 0.2 * hole.min_radius_of_curvature)


def solve_cup(g: CupGeometry, hole, forces, h: float, points) -> np.ndarray:
    """Displacements ``(frames, n, 3)`` at ``points (n, 3)`` of the cup holder with ``hole`` (an
    ``Ellipse`` or None) meshed with ``tet10`` at ``h`` (finer along the hole: :func:`data_hole_h`), rim held, each total force of
    ``forces`` (N, upwards) spread uniformly over the bottom's outer face."""
    cup = cup_holder(g.r_in, g.r_out, g.height, g.bottom, h, hole=hole, hole_h=data_hole_h(hole, h))
    mesh, facets = cup.mesh, cup.bottom_outer_facets
    problem = jf.Problem(mesh, g.law, "solid", fixed=jf.dofs(mesh, cup.sets["rim"]), traction_facets=facets)
    solver = jf.Solver(problem)
    X = mesh.nodes
    a, b, c = X[facets[:, 0]], X[facets[:, 1]], X[facets[:, 2]]
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1).sum()
    probe = jf.locate(mesh, points, tol=0.05)  # points on the circles lie a chord's sagitta outside
    out, start = [], None
    for F in forces:
        theta = problem.params(E=g.E, nu=g.nu, traction=np.array([0.0, 0.0, F / area]))
        sol = solver.solve(theta, start=start)
        start = (sol.u.reshape(-1), {"u_D": theta["u_D"], "f": theta["f"], "traction": theta["traction"]})
        out.append(np.asarray(probe(sol.u)))
    return np.stack(out)


def cup_bundle(geometry: CupGeometry = CupGeometry(), hole: jf.Ellipse | None = None,
               forces=(1.0, 2.0, 3.0), h_data: float = 1.0, h_model: float = 2.0, spacing: float = 1.2,
               noise: float = 0.01, seed: int = 0) -> tuple[Bundle, jf.Mesh]:
    """A cup-holder bundle (see the module) and its model mesh (the cup holder without a hole at
    ``h_model``, tet10).

    Args:
        geometry: dimensions and material; hole: the hidden hole (None: a sound cup holder).
        forces: total squeeze force per frame (N), 2-4 frames.
        h_data: the data's element size (mm), finer than ``h_model``; spacing: the painted grid's
            pitch (mm); noise: standard deviation of each displacement component (mm; a
            structured-light scanner's 0.005-0.02 mm at this size); seed: the grid's placement,
            the roles and the noise.
    """
    if not 2 <= len(forces) <= 4:
        raise ValueError(f"a cup-holder sequence has 2-4 frames, got {len(forces)} forces")
    rng = np.random.default_rng(seed)
    X, roles = _points(geometry, hole, spacing, rng)
    U = solve_cup(geometry, hole, forces, h_data, X) + rng.normal(0.0, noise, (len(forces), *X.shape))
    F = np.zeros((len(forces), 1, 3))
    F[:, 0, 2] = forces
    obs = Observations(np.arange(1, len(X) + 1), X, roles, U, forces=Forces(("back",), F))
    g = geometry
    exp = Experiment(name="cup-holder", kind="solid", domain=MeshDomain("mesh.vtu"), law=g.law, E=g.E, nu=g.nu,
                     units={"length": "mm", "stress": "MPa", "force": "N"}, noise_std=noise)
    return Bundle(exp, obs), cup_holder(g.r_in, g.r_out, g.height, g.bottom, h_model).mesh


def write_cup_bundle(root: str | Path, **kw) -> Path:
    """:func:`cup_bundle` written to the directory ``root`` (with ``mesh.vtu``); returns it."""
    bundle, mesh = cup_bundle(**kw)
    root = Path(root)
    root.mkdir(parents=True, exist_ok=True)
    jf.write_vtu(root / "mesh.vtu", mesh)
    return write_bundle(root, bundle)
