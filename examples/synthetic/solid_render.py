"""Intensity and range images of a deformed solid's visible surface, with the truth per pixel.

A grid is painted on the body in REFERENCE coordinates (it moves with the material): ink where a
reference coordinate along either of two axes is within half a line width of a multiple of the
pitch, with error-function edges (analytic anti-aliasing), so a painted crossing is the material
point where both coordinates are multiples of the pitch. The surface is the mesh's boundary
facets (a quadratic facet is split at its mid-edge nodes into 4 flat triangles), moved by the
nodal displacement, and rasterised with a z-buffer through a :class:`tracking.Camera`
(:mod:`examples.synthetic.rasterise`).

- the intensity image: paint (``levels``) times a Lambertian shading, evaluated on a lattice
  ``supersample`` times finer than the pixels, blurred by the optics (``blur_sigma`` px), averaged
  over each pixel, plus sensor noise (``noise_sigma`` grey levels); nothing seen: ``background``.
- the range image: the depth at each pixel centre (camera axis, the camera's length unit) plus
  Gaussian noise of ``depth_noise`` (a structured-light scanner: 0.02 to 0.1 mm), NaN where the
  ray meets no surface. Pixels out of the image simply are not there: part of a body may be out of
  view.
- the truth: each pixel centre's reference material point and its deformed (noise-free) position.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from scipy.special import erf

from jaxfem.surface import FACE_TRIANGLES

from refine.exceptions import RefineError
from examples.synthetic.rasterise import rasterise

_SPLIT = np.asarray(FACE_TRIANGLES["tri6"])  # a tri6 facet (corners, then mid-edges 01, 12, 20)


@dataclass(frozen=True)
class SurfaceGrid:
    """Lines painted on a body, in its reference coordinates (length unit).

    Attributes:
        pitch: distance between lines.
        line_width: width of a line.
        edge: standard deviation of the error-function edge of a line (anti-aliasing), length.
        origin: a reference point where two lines cross, ``(3,)``.
        axes: the two reference directions ``(2, 3)`` whose coordinates the lines are levels of
            (default x and y: lines x = origin_x + k pitch and y = origin_y + k pitch).
    """

    pitch: float = 1.25
    line_width: float = 0.22
    edge: float = 0.03
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)
    axes: tuple[tuple[float, ...], tuple[float, ...]] = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0))

    def ink(self, X: np.ndarray) -> np.ndarray:
        """Ink coverage in [0, 1] at reference points ``(..., 3)``."""
        local = (np.asarray(X, np.float64) - np.asarray(self.origin)) @ np.asarray(self.axes, np.float64).T
        d = np.abs(local - self.pitch * np.round(local / self.pitch))
        k = 1.0 / (np.sqrt(2.0) * self.edge)
        line = 0.5 * (erf((d + 0.5 * self.line_width) * k) - erf((d - 0.5 * self.line_width) * k))
        return line.max(axis=-1)


@dataclass(frozen=True)
class SolidView:
    """One rendered frame.

    Attributes:
        image: ``(rows, cols)`` float grey levels 0-255.
        range: ``(rows, cols)`` depth with noise, NaN where nothing is seen.
        material: ``(rows, cols, 3)`` the reference material point each pixel centre sees (NaN: none).
        position: ``(rows, cols, 3)`` its deformed position, world axes, without noise (NaN: none).
    """

    image: np.ndarray
    range: np.ndarray
    material: np.ndarray
    position: np.ndarray


def surface_triangles(facets: np.ndarray) -> np.ndarray:
    """Flat triangles ``(m, 3)`` of node indices from boundary facets ``(n, 3)`` (tri3) or ``(n, 6)``
    (tri6, split at the mid-edge nodes into 4)."""
    facets = np.asarray(facets, np.int64)
    if facets.shape[1] == 3:
        return facets
    if facets.shape[1] != 6:
        raise RefineError(f"surface facets must have 3 or 6 nodes, got {facets.shape[1]}")
    return facets[:, _SPLIT].reshape(-1, 3)


def render_solid(nodes: np.ndarray, facets: np.ndarray, u: np.ndarray | None, camera, shape: tuple[int, int],
                 paint: SurfaceGrid = SurfaceGrid(), *, depth_noise: float = 0.05, supersample: int = 4,
                 blur_sigma: float = 0.8, noise_sigma: float = 2.0, levels: tuple[float, float] = (200.0, 50.0),
                 background: float = 15.0, ambient: float = 0.3, seed: int = 0, cull: bool = True) -> SolidView:
    """Render a deformed solid's visible surface as intensity and range images, with the truth.

    Args:
        nodes: ``(n, 3)`` reference node positions (length unit of the camera, e.g. mm).
        facets: ``(m, 3 or 6)`` the body's boundary facets (``mesh.boundary_facets()``).
        u: ``(n, 3)`` nodal displacement; None: the reference shape.
        camera: a :class:`tracking.Camera` (world axes = the mesh's axes).
        shape: image ``(rows, cols)``.
        paint: the grid painted on the body.
        depth_noise: standard deviation of the range noise, length unit.
        supersample, blur_sigma, noise_sigma: the intensity image's samples per pixel side, optics
            blur (px) and sensor noise (grey levels).
        levels: grey levels of the bare surface and of the ink (fully lit).
        background: grey level where no surface is seen.
        ambient: share of the light that does not depend on the surface's slope (Lambertian rest).
        seed: seed of the noises (the range noise uses ``seed + 1``).
        cull: skip the facets that face away from the camera (needs outward-oriented facets, as
            ``jaxfem`` meshes' boundary facets are; False for a surface of unknown orientation).

    Returns:
        :class:`SolidView`.
    """
    X = np.asarray(nodes, np.float64)
    x = X if u is None else X + np.asarray(u, np.float64)
    tri = surface_triangles(facets)
    normal = np.cross(x[tri[:, 1]] - x[tri[:, 0]], x[tri[:, 2]] - x[tri[:, 0]])
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
    # light along the viewing direction: the camera's axis (orthographic) or the ray (perspective)
    centre = x[tri].mean(axis=1)
    view = centre - camera.translation if camera.perspective else np.broadcast_to(camera.rotation[:, 2], centre.shape)
    view = view / np.linalg.norm(view, axis=1, keepdims=True)
    facing = np.einsum("ij,ij->i", normal, view)
    if cull:                                   # outward facets turned away from the camera are hidden anyway
        tri, facing = tri[facing < 0], facing[facing < 0]
    shade = ambient + (1.0 - ambient) * np.abs(facing)
    uv, z = camera.project(x[tri])                                       # (m, 3, 2), (m, 3)

    fine = rasterise(uv, z, shape, supersample, camera.perspective)
    material = fine.interpolate(X[tri])
    seen = fine.triangle >= 0
    bare, ink_level = levels
    grey = np.full(seen.shape, float(background))
    grey[seen] = shade[fine.triangle[seen]] * (bare + (ink_level - bare) * paint.ink(material[seen]))
    s = fine.supersample
    if blur_sigma > 0:
        grey = ndimage.gaussian_filter(grey, blur_sigma * s, mode="nearest")
    image = grey.reshape(shape[0], s, shape[1], s).mean(axis=(1, 3))
    rng = np.random.default_rng(seed)
    if noise_sigma > 0:
        image = image + rng.normal(0.0, noise_sigma, image.shape)

    centres = fine if s == 1 else rasterise(uv, z, shape, 1, camera.perspective)
    depth = centres.depth + (np.random.default_rng(seed + 1).normal(0.0, depth_noise, shape) if depth_noise > 0 else 0)
    return SolidView(np.clip(image, 0.0, 255.0), depth, centres.interpolate(X[tri]), centres.interpolate(x[tri]))


def surface_distance(points: np.ndarray, nodes: np.ndarray, facets: np.ndarray, u: np.ndarray | None = None,
                     samples: int = 6, candidates: int = 8) -> np.ndarray:
    """Distance from ``points`` ``(p, 3)`` to a deformed body's surface (the truth of a cloud), ``(p,)``.

    The surface's flat triangles (:func:`surface_triangles`, moved by ``u``) are sampled on a
    barycentric lattice of ``samples`` steps per side; the triangles of a point's ``candidates``
    nearest samples are its candidates, and its distance is the exact point-to-triangle distance to
    the nearest of them.
    """
    from scipy.spatial import cKDTree

    x = np.asarray(nodes, np.float64) + (0.0 if u is None else np.asarray(u, np.float64))
    tri = surface_triangles(facets)
    corners = x[tri]                                                                       # (m, 3, 3)
    i, j = np.meshgrid(np.arange(samples + 1), np.arange(samples + 1), indexing="ij")
    keep = i + j <= samples
    bary = np.stack([i[keep], j[keep], samples - i[keep] - j[keep]], axis=1) / samples     # (s, 3)
    cloud = np.einsum("sk,mkd->msd", bary, corners).reshape(-1, 3)
    owner = np.repeat(np.arange(len(tri)), len(bary))
    _, nearest = cKDTree(cloud).query(np.asarray(points, np.float64), k=candidates)
    P = np.asarray(points, np.float64)[:, None, :]
    A, B, C = (corners[owner[nearest]][..., k, :] for k in range(3))                     # (p, k, 3)
    return _triangle_distance(P, A, B, C).min(axis=1)


def _triangle_distance(P, A, B, C) -> np.ndarray:
    """Exact distance from points P to triangles ABC (broadcast ``(..., 3)``): to the plane where the
    foot lies inside, else to the nearest edge."""
    n = np.cross(B - A, C - A)
    area2 = np.einsum("...d,...d->...", n, n)
    n_hat = n / np.sqrt(np.maximum(area2, 1e-300))[..., None]
    h = np.einsum("...d,...d->...", P - A, n_hat)
    foot = P - h[..., None] * n_hat

    def side(a, b):
        return np.einsum("...d,...d->...", np.cross(b - a, foot - a), n)

    inside = (side(A, B) >= 0) & (side(B, C) >= 0) & (side(C, A) >= 0) & (area2 > 0)

    def segment(a, b):
        ab = b - a
        t = np.clip(np.einsum("...d,...d->...", P - a, ab) / np.maximum(np.einsum("...d,...d->...", ab, ab), 1e-300),
                    0.0, 1.0)
        return np.linalg.norm(P - (a + t[..., None] * ab), axis=-1)

    edges = np.minimum(np.minimum(segment(A, B), segment(B, C)), segment(C, A))
    return np.where(inside, np.abs(h), edges)
