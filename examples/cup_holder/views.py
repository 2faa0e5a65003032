"""The paper's Sec. 4 experiment, synthesised: a foam cup holder compressed on its bottom, seen
from below by a camera with a range scanner, frame by frame.

The cup holder (:func:`examples.cup_holder.cup_holder`, tet10, axis z, bottom face z = 0, rim z = height) is
held at its rim and pushed up by a uniform dead load on its bottom's outer face; the solve runs on
a fine mesh (``h`` 1.5 mm by default, never the inversion's). A grid is painted on the bottom in
reference coordinates (lines x = k pitch and y = k pitch, a crossing at the axis); each frame is
rendered as an intensity image and a range image (:func:`examples.synthetic.solid_render.render_solid`)
through a camera below the bottom looking up the axis (camera axes = world axes, shifted), with
the image window off-centre so that part of the bottom is out of view. The truth: the painted
crossings' material points and their positions in every frame.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

import jaxfem as jf
from examples.cup_holder import CupHolder, cup_holder
import tracking

from examples.cup_holder.synthetic import data_hole_h
from examples.synthetic.solid_render import SolidView, SurfaceGrid, render_solid

R_IN, R_OUT, HEIGHT, BOTTOM = 8.0, 11.0, 8.0, 3.0  # mm


@dataclass(frozen=True)
class CupScene:
    """The cup holder's dimensions (mm), its material, the camera and what is painted.

    Attributes:
        r_in, r_out, height, bottom: the cup holder (mm).
        E, nu: neo-Hookean background (MPa), foam-like.
        hole: a through-thickness elliptic hole in the bottom (:class:`jaxfem.Ellipse`), or None.
        camera: the range camera (mm; world axes = the mesh's).
        shape: image ``(rows, cols)``.
        paint: the grid on the bottom.
        depth_noise: range noise, mm (structured light: 0.02 to 0.1 mm).
        noise_sigma: intensity noise, grey levels.
    """

    r_in: float = R_IN
    r_out: float = R_OUT
    height: float = HEIGHT
    bottom: float = BOTTOM
    E: float = 1.0
    nu: float = 0.45
    hole: jf.Ellipse | None = None
    camera: tracking.Camera = field(default_factory=lambda: cup_camera())
    shape: tuple[int, int] = (200, 240)
    paint: SurfaceGrid = SurfaceGrid(pitch=1.25, line_width=0.22, edge=0.03)
    depth_noise: float = 0.05
    noise_sigma: float = 2.0

    def mesh(self, h: float, element: str = "tet10") -> CupHolder:
        """The cup holder meshed at element size ``h`` (mm), finer along the hole
        (:func:`examples.cup_holder.synthetic.data_hole_h`: the data's hole is the drawn ellipse to 0.2 %)."""
        return cup_holder(self.r_in, self.r_out, self.height, self.bottom, h, hole=self.hole, element=element,
                             hole_h=data_hole_h(self.hole, h))


def cup_camera(model: str = "orthographic", scale: float = 0.1, distance: float = 60.0,
               centre_px: tuple[float, float] = (85.3, 100.2)) -> tracking.Camera:
    """A camera ``distance`` mm below the bottom looking up the axis (camera axes = world axes), the
    axis seen at pixel ``centre_px``; ``scale`` mm per px at the bottom's face (perspective: fx = fy =
    distance / scale). The default puts the axis 85 px from the left of a 240 px wide image: the
    bottom's left edge (11 mm = 110 px from the axis) is out of view, and so are its top and bottom
    in 200 rows."""
    cx, cy = centre_px
    if model == "orthographic":
        return tracking.Camera("orthographic", scale=scale, cx=cx, cy=cy, translation=[0.0, 0.0, -distance])
    f = distance / scale
    return tracking.Camera("perspective", fx=f, fy=f, cx=cx, cy=cy, translation=[0.0, 0.0, -distance])


def compressed_cup(scene: CupScene, forces=(1.0, 2.0), h: float = 1.5) -> tuple[CupHolder, list[np.ndarray]]:
    """Solve the cup holder held at its rim under total upward loads ``forces`` (N) spread uniformly on
    its bottom's outer face (a dead load), on a tet10 mesh of size ``h``: the mesh and the nodal
    displacements ``(n_nodes, 3)`` mm per load."""
    cup = scene.mesh(h)
    mesh, facets = cup.mesh, cup.bottom_outer_facets
    problem = jf.Problem(mesh, "neo-hookean", "solid", fixed=jf.dofs(mesh, cup.sets["rim"]), traction_facets=facets)
    solver = jf.Solver(problem)
    area = _area(mesh.nodes, facets)
    loads = [problem.params(E=scene.E, nu=scene.nu, traction=np.array([0.0, 0.0, F / area])) for F in forces]
    return cup, [np.asarray(solver.solve(theta).u) for theta in loads]


def render_cup(scene: CupScene, cup: CupHolder, displacements, seed: int = 0) -> list[SolidView]:
    """The reference frame and one frame per displacement, rendered (noise from ``seed + 2 k``)."""
    facets = cup.mesh.boundary_facets()
    return [render_solid(cup.mesh.nodes, facets, u, scene.camera, scene.shape, scene.paint,
                         depth_noise=scene.depth_noise, noise_sigma=scene.noise_sigma, seed=seed + 2 * k)
            for k, u in enumerate([None, *displacements])]


def painted_crossings(scene: CupScene, cup: CupHolder, displacements, margin: float = 0.6) -> np.ndarray:
    """The painted crossings on the bottom's face at least ``margin`` mm from its edge and from the
    hole: their positions ``(n_frames, n, 3)`` mm, frame 0 the reference (material points)."""
    p, (ox, oy, _) = scene.paint.pitch, scene.paint.origin
    k = np.arange(-np.ceil(scene.r_out / p) - 1, np.ceil(scene.r_out / p) + 2)
    X = np.stack(np.meshgrid(ox + k * p, oy + k * p), -1).reshape(-1, 2)
    keep = np.hypot(X[:, 0], X[:, 1]) < scene.r_out - margin
    if scene.hole is not None:
        h = scene.hole
        keep &= ~np.asarray(jf.Ellipse(h.cx, h.cy, h.rx + margin, h.ry + margin, h.angle).contains(X), bool)
    X = np.c_[X[keep], np.zeros(keep.sum())]
    probe = jf.locate(cup.mesh, X, tol=1e-6)
    return np.stack([X] + [X + np.asarray(probe(u)) for u in displacements])


def _area(X, facets) -> float:
    a, b, c = X[facets[:, 0]], X[facets[:, 1]], X[facets[:, 2]]
    return 0.5 * float(np.linalg.norm(np.cross(b - a, c - a), axis=1).sum())


def write_frames(views, directory) -> tuple[list, list]:
    """Write rendered frames as ``img_K.png`` (8-bit) and ``range_K.npy`` (float32 mm, NaN: no data)
    into ``directory`` (created); returns the image paths and the range paths."""
    import cv2
    from pathlib import Path

    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    images, ranges = [], []
    for k, view in enumerate(views):
        images.append(directory / f"img_{k}.png")
        ranges.append(directory / f"range_{k}.npy")
        cv2.imwrite(str(images[-1]), np.clip(np.rint(view.image), 0, 255).astype(np.uint8))
        np.save(ranges[-1], view.range.astype(np.float32))
    return images, ranges


def crossing_errors(reference: np.ndarray, displacements: np.ndarray, truth: np.ndarray,
                    tol: float | None = None) -> dict:
    """How far tracked 3D points lie from the painted crossings they track.

    Args:
        reference: ``(n, 3)`` tracked reference positions (points.csv), mm.
        displacements: ``(n_frames, n, 3)`` tracked displacements (NaN where lost), mm.
        truth: ``(n_frames + 1, m, 3)`` :func:`painted_crossings`.
        tol: points farther than this (mm) from every true crossing in the reference are left out
            (crossings nearer the hole or the edge than the truth's margin); None: none left out.

    Returns:
        ``{"matched": largest distance to the nearest true crossing in the reference, "kept": the
        points compared, "rms_xy", "rms_z", "max_z": per frame from 0 (positions), "rms_uz",
        "rms_u", "max_u": per deformed frame (displacement errors along the axis; per axis x, y,
        z), "lost": per deformed frame}``, mm.
    """
    from scipy.spatial import cKDTree

    distance, match = cKDTree(truth[0]).query(reference)
    kept = np.ones(len(distance), bool) if tol is None else distance < tol
    reference, displacements, distance, match = reference[kept], displacements[:, kept], distance[kept], match[kept]
    positions = np.concatenate([reference[None], reference[None] + displacements])
    out = {"matched": float(distance.max()), "kept": int(kept.sum()), "rms_xy": [], "rms_z": [], "max_z": [],
           "rms_uz": [], "rms_u": [], "max_u": [], "lost": []}
    for f, p in enumerate(positions):
        ok = np.isfinite(p).all(axis=1)
        e = p[ok] - truth[f][match[ok]]
        out["rms_xy"].append(float(np.sqrt(np.mean(np.sum(e[:, :2] ** 2, axis=1)))))
        out["rms_z"].append(float(np.sqrt(np.mean(e[:, 2] ** 2))))
        out["max_z"].append(float(np.abs(e[:, 2]).max()))
        if f:
            du = displacements[f - 1, ok] - (truth[f][match[ok]] - truth[0][match[ok]])
            out["rms_uz"].append(float(np.sqrt(np.mean(du[:, 2] ** 2))))
            out["rms_u"].append(np.sqrt(np.mean(du ** 2, axis=0)).tolist())
            out["max_u"].append(np.abs(du).max(axis=0).tolist())
            out["lost"].append(int((~ok).sum()))
    return out


@dataclass(frozen=True)
class CupFrames:
    """A rendered compressed cup holder on disk (:func:`write_cup_frames`): intensity and range
    images (frame 0 the reference), the modeller's mesh (no hole), the total squeeze forces ``(N,)``
    per deformed frame, and the truth (:func:`painted_crossings`, ``(n_frames + 1, m, 3)`` mm)."""

    images: list
    ranges: list
    mesh: object
    forces: tuple
    truth: np.ndarray


def write_cup_frames(directory, scene: CupScene, forces=(1.0, 2.0, 3.0), h: float = 1.2, h_model: float = 2.0,
                     seed: int = 0) -> CupFrames:
    """Solve ``scene`` under ``forces`` on a tet10 mesh of size ``h`` (mm), render every frame
    (noise from ``seed``) and write the images, range images and the modeller's mesh without the
    hole at ``h_model`` (``mesh.vtu``) into ``directory``: the input of ``nonrigid track --range``."""
    from pathlib import Path

    cup, U = compressed_cup(scene, forces, h)
    images, ranges = write_frames(render_cup(scene, cup, U, seed=seed), directory)
    mesh = Path(directory) / "mesh.vtu"
    jf.write_vtu(mesh, cup_holder(scene.r_in, scene.r_out, scene.height, scene.bottom, h_model).mesh)
    return CupFrames(images, ranges, mesh, tuple(float(f) for f in forces), painted_crossings(scene, cup, U))


def add_squeeze_forces(root, forces) -> None:
    """Write the load cell's total squeeze forces ``forces (N,)`` (N, upward, one per frame, frame 0
    the reference) into the tracked bundle at ``root`` as forces.csv on the side ``back`` (the
    bottom's outer face), as a user adds a measured force to what ``nonrigid track`` wrote."""
    from dataclasses import replace

    from refine.bundle.io import read_bundle, write_bundle
    from refine.bundle.observations import Forces

    b = read_bundle(root)
    F = np.zeros((len(forces), 1, 3))
    F[:, 0, 2] = forces
    write_bundle(root, replace(b, observations=replace(b.observations, forces=Forces(("back",), F))))
