"""Images of a pulled sheet that hides an inclusion, for tests and notebooks (tracking meets FE).

The sheet is solved once per load fraction with the same fine quadratic mesh that
:func:`refine.demo_data.synthetic_bundle` uses; each frame's displacement is resampled once onto a
regular lattice (``jaxfem.locate``) so that the renderer, which evaluates the field a few dozen
times at every sub-pixel, only pays for a bilinear interpolation.

Image axes are the sheet's axes: pixel (col, row) shows the sheet point (x, y) = (col, row) *
scale in mm, so coordinates that ``nonrigid track`` writes (x = col * scale, y = row * scale)
are directly comparable with the hidden :class:`~refine.demo_data.Truth`.

The camera follows the centre of the region of interest (a rigid translation is removed from every
frame): a clamped sheet pulled from one side moves the whole region by far more than a grid pitch
between frames, which no frame-to-frame tracker follows, while a rigid translation changes neither
the strains nor anything ``nonrigid diagnose`` looks at.
"""

from __future__ import annotations

from typing import Callable, Sequence

import numpy as np
from scipy.interpolate import RegularGridInterpolator, griddata
from scipy.spatial import cKDTree

import jaxfem as jf
import tracking

from refine.exceptions import RefineError
from refine.demo_data import Truth, _fine_solution

Displacement = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]

SHEET = (0.0, 0.0, 140.0, 80.0)
ROI = (20.0, 10.0, 120.0, 70.0)


def sheet_displacements(truth: Truth, fractions: Sequence[float], scale_mm_per_px: float, *,
                        sheet=SHEET, follow=None, pull: float = 0.15, h: float = 2.0,
                        resolution: float | None = None) -> list[Displacement]:
    """Displacement fields of the pulled sheet, one per load fraction, in pixels of the images.

    The sheet ``[x0, y0, x1, y1]`` mm is clamped at its left side and its right side is pulled by
    ``fraction * pull`` times its width; ``truth`` says what it hides.

    Args:
        truth: the hidden inclusions and holes, E, nu, thickness (mm and the stress unit).
        fractions: load fractions of the frames after the reference, e.g. ``(0.5, 1.0)``.
        scale_mm_per_px: length of a pixel, mm.
        follow: (x, y) mm of the point the camera follows (its displacement is removed from every
            frame); None keeps the laboratory frame.
        pull: final stretch of the sheet (0.15 = 15 %).
        h: element size of the fine mesh, mm.
        resolution: spacing of the resampling lattice, mm (default ``h / 2``: bilinear
            interpolation then misses the fine solution by ~1e-3 mm rms, ~0.03 mm at most, at an
            inclusion's edge, for the default 15 % pull).

    Returns:
        Callables ``u(X, Y) -> (ux, uy)`` on reference pixel coordinates (any equal shapes), in
        pixels, as :func:`tracking.render_grid` and :func:`tracking.render_speckle` take them.
        Outside the sheet the field is extended linearly.
    """
    mesh, U, _ = _fine_solution(truth, sheet, pull, tuple(fractions), h)
    x0, y0, x1, y1 = sheet
    step = resolution or 0.5 * h
    xs = np.linspace(x0, x1, int(np.ceil((x1 - x0) / step)) + 1)
    ys = np.linspace(y0, y1, int(np.ceil((y1 - y0) / step)) + 1)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    points = np.stack([X.ravel(), Y.ravel()], 1)
    # lattice points in a hole (or a step from it: the mesh's hole is a polygon) are not on the
    # mesh; they get values interpolated linearly from around the hole (the renderer shows no
    # material there but evaluates the field while inverting the map)
    on_mesh = np.ones(len(points), bool)
    for hole in truth.holes:
        inside = points[np.asarray(hole.contains(points), bool)]
        if len(inside):
            on_mesh &= ~np.isfinite(cKDTree(inside).query(points, distance_upper_bound=1.5 * step)[0])
    probe = jf.locate(mesh, points[on_mesh])
    shift = np.zeros((len(U), 2))
    if follow is not None:
        at = jf.locate(mesh, np.asarray(follow, float).reshape(1, 2))
        shift = np.stack([np.asarray(at(u))[0] for u in U])
    scale = float(scale_mm_per_px)
    fields = []
    for u, t in zip(U, shift):
        values = np.asarray(probe(u)) - t
        if not on_mesh.all():
            values = _filled(points, on_mesh, values)
        values = values.reshape(len(xs), len(ys), 2) / scale
        fields.append(_lattice_field(xs / scale, ys / scale, values))
    return fields


def _filled(points: np.ndarray, known: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Values (n, 2) at all ``points`` (n, 2): ``values`` where ``known``, linear in between."""
    out = np.empty((len(points), values.shape[1]))
    out[known] = values
    out[~known] = griddata(points[known], values, points[~known], method="linear")
    return out


def _lattice_field(xs: np.ndarray, ys: np.ndarray, values: np.ndarray) -> Displacement:
    """Bilinear interpolation of ``values (len(xs), len(ys), 2)`` given on the lattice xs x ys."""
    interpolate = RegularGridInterpolator((xs, ys), values, bounds_error=False, fill_value=None)

    def displacement(x, y):
        x, y = np.asarray(x, float), np.asarray(y, float)
        u = interpolate(np.stack([x.ravel(), y.ravel()], 1))
        return u[:, 0].reshape(x.shape), u[:, 1].reshape(x.shape)

    return displacement


def render_sheet_images(truth: Truth, frames: Sequence[float] | int = (0.5, 1.0), pitch_px: float = 12.0,
                        scale_mm_per_px: float = 0.5, *, pattern: str = "grid", roi=ROI, sheet=SHEET,
                        pull: float = 0.15, h: float = 2.0, line_width: float = 2.0,
                        blur_sigma: float = 1.0, noise_sigma: float = 2.0, seed: int = 0,
                        supersample: int = 4):
    """Camera images of the sheet hiding ``truth``: a reference frame and one per load fraction.

    A grid of lines every ``pitch_px`` px (``pattern="grid"``, a crossing at the ROI's top-left
    corner) or a speckle pattern (``pattern="speckle"``, speckles of ``pitch_px / 8`` px sigma)
    is painted on the sheet. The image shows the sheet from (0, 0) mm at pixel (0, 0) to beyond
    the region of interest in every frame (two pitches of margin); the camera follows the ROI's
    centre (see the module docstring).

    Args:
        truth: the hidden effect (see :func:`refine.demo_data.random_truth`), mm.
        frames: load fractions after the reference, e.g. ``(0.5, 1.0)``, or their number n
            (fractions 1/n, 2/n, ..., 1).
        pitch_px: grid pitch (or speckle size scale), px.
        scale_mm_per_px: mm per pixel.
        roi: tracked region ``[x0, y0, x1, y1]``, mm.
        sheet: the whole sheet ``[x0, y0, x1, y1]``, mm; clamped left, pulled right by ``pull``.
        blur_sigma, noise_sigma, seed, supersample: as :func:`tracking.render_pattern`
            (noise in grey levels, seed of the noise of frame 0; frame k uses ``seed + k``).

    Returns:
        ``(images, roi_px, scale)``: images ``(n_frames + 1, rows, cols)`` float 0-255 with the
        reference first; ``roi_px = (x0, y0, x1, y1)`` pixels of the first image, the ROI widened
        by half a pitch so that grid crossings on its edges are tracked; ``scale`` in mm/px.
    """
    if pattern not in ("grid", "speckle"):
        raise RefineError(f"unknown pattern {pattern!r}; use 'grid' or 'speckle'")
    if isinstance(frames, (int, np.integer)):
        frames = tuple((k + 1) / frames for k in range(int(frames)))
    scale = float(scale_mm_per_px)
    x0, y0, x1, y1 = roi
    centre = (0.5 * (x0 + x1), 0.5 * (y0 + y1))
    fields = sheet_displacements(truth, frames, scale, sheet=sheet, follow=centre, pull=pull, h=h)
    corners = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]]) / scale
    reach = np.concatenate([corners] + [tracking.deformed_points(corners, u) for u in fields])
    margin = 2.0 * pitch_px
    shape = (int(np.ceil(reach[:, 1].max() + margin)), int(np.ceil(reach[:, 0].max() + margin)))
    if reach.min() < 0:
        raise RefineError(f"the region of interest {tuple(roi)} mm leaves the image at (0, 0) while the sheet "
                          "deforms; keep it far enough from the sheet's (0, 0) corner")
    common = dict(blur_sigma=blur_sigma, noise_sigma=noise_sigma, supersample=supersample)
    images = []
    for k, u in enumerate([None, *fields]):
        if pattern == "grid":
            image = tracking.render_grid(shape, pitch_px, line_width, u, seed=seed + k,
                                         origin=(x0 / scale, y0 / scale), **common)
        else:
            image = tracking.render_speckle(shape, pitch_px / 8.0, u, seed=seed + k, pattern_seed=seed, **common)
        images.append(image)
    half = 0.5 * pitch_px
    roi_px = (max(0.0, x0 / scale - half), max(0.0, y0 / scale - half),
              min(shape[1], x1 / scale + half), min(shape[0], y1 / scale + half))
    return np.stack(images), roi_px, scale
