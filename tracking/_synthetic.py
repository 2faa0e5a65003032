"""Synthetic images with known motion, for tests and benchmarks (no finite elements here).

A pattern is an analytic "ink" function of reference coordinates X (pixels). A deformed image
shows the pattern moved by a displacement field u: the material point X is seen at x = X + u(X).
Rendering inverts that map for every (sub)pixel by fixed-point iterations X <- x - u(X), which
converge when the displacement gradient stays below 1 (e.g. any stretch under 100 %).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy import ndimage
from scipy.special import erf

from ._errors import TrackingError

Displacement = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]


@dataclass(frozen=True)
class GridPattern:
    """Straight lines of ``line_width`` px every ``pitch`` px in two perpendicular families.

    Line edges are softened by an error function of width ``edge_sigma`` (analytic anti-aliasing);
    where lines cross the paint does not add up (opaque ink). A crossing sits at ``origin``.
    """

    pitch: float = 12.0
    line_width: float = 2.0
    origin: tuple[float, float] = (0.0, 0.0)
    angle_deg: float = 0.0
    edge_sigma: float = 0.3

    def _local(self, x, y):
        c, s = np.cos(np.radians(self.angle_deg)), np.sin(np.radians(self.angle_deg))
        dx, dy = x - self.origin[0], y - self.origin[1]
        return c * dx + s * dy, -s * dx + c * dy

    def _line(self, u):
        d = np.abs(u - self.pitch * np.round(u / self.pitch))
        k = 1.0 / (np.sqrt(2.0) * self.edge_sigma)
        return 0.5 * (erf((d + 0.5 * self.line_width) * k) - erf((d - 0.5 * self.line_width) * k))

    def ink(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Ink coverage in [0, 1] at reference points (x, y) (pixels, any equal shapes)."""
        u, v = self._local(x, y)
        return np.maximum(self._line(u), self._line(v))

    def crossings(self, x0: float, y0: float, x1: float, y1: float) -> tuple[np.ndarray, np.ndarray]:
        """Reference crossings inside [x0, x1] x [y0, y1]: xy (n, 2) and their (row, col) (n, 2)."""
        corners = np.array([[x0, y0], [x1, y0], [x0, y1], [x1, y1]], dtype=np.float64)
        u, v = self._local(corners[:, 0], corners[:, 1])
        i = np.arange(np.floor(v.min() / self.pitch) - 1, np.ceil(v.max() / self.pitch) + 2)
        j = np.arange(np.floor(u.min() / self.pitch) - 1, np.ceil(u.max() / self.pitch) + 2)
        jj, ii = np.meshgrid(j, i)
        c, s = np.cos(np.radians(self.angle_deg)), np.sin(np.radians(self.angle_deg))
        uu, vv = jj.ravel() * self.pitch, ii.ravel() * self.pitch
        xy = np.stack([self.origin[0] + c * uu - s * vv, self.origin[1] + s * uu + c * vv], axis=1)
        keep = (xy[:, 0] >= x0) & (xy[:, 0] <= x1) & (xy[:, 1] >= y0) & (xy[:, 1] <= y1)
        index = np.stack([ii.ravel(), jj.ravel()], axis=1).astype(np.int64)
        return xy[keep], index[keep]


@dataclass(frozen=True)
class SpecklePattern:
    """Random speckles: Gaussian dots of ``speckle_sigma`` px, one per cell of a jittered lattice.

    The dots' positions and strengths come from ``seed``, so the same pattern can be rendered in
    every frame; ink = 1 - exp(-sum of dots) saturates where dots overlap, as paint does.
    """

    speckle_sigma: float = 1.2
    cell: float = 3.0
    seed: int = 0
    table: int = 256

    def _tables(self):
        rng = np.random.default_rng(self.seed)
        jitter = rng.random((2, self.table, self.table))
        strength = 0.6 + 0.9 * rng.random((self.table, self.table))
        return jitter, strength

    def ink(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Ink coverage in [0, 1] at reference points (x, y) (pixels, any equal shapes)."""
        jitter, strength = self._tables()
        shape = np.shape(x)
        x, y = np.ravel(x), np.ravel(y)
        reach = int(np.ceil(4.0 * self.speckle_sigma / self.cell))
        out = np.empty(x.size)
        for start in range(0, x.size, 200_000):
            xs, ys = x[start:start + 200_000], y[start:start + 200_000]
            ci, cj = np.floor(ys / self.cell).astype(np.int64), np.floor(xs / self.cell).astype(np.int64)
            total = np.zeros(xs.size)
            for di in range(-reach, reach + 1):
                for dj in range(-reach, reach + 1):
                    ti, tj = (ci + di) % self.table, (cj + dj) % self.table
                    cx = (cj + dj + jitter[0, ti, tj]) * self.cell
                    cy = (ci + di + jitter[1, ti, tj]) * self.cell
                    r2 = (xs - cx) ** 2 + (ys - cy) ** 2
                    total += strength[ti, tj] * np.exp(-0.5 * r2 / self.speckle_sigma ** 2)
            out[start:start + xs.size] = 1.0 - np.exp(-total)
        return out.reshape(shape)


@dataclass(frozen=True)
class Scene:
    """What a camera sees besides the pattern: the specimen's extent, holes, a glare patch.

    The specimen and its holes are material features (reference pixels: they move with the
    displacement); beyond the specimen and inside a hole the camera sees a uniform dark
    ``background``. The glare is light on the camera's side (image pixels: it stays put while the
    material moves under it): a Gaussian of ``glare[2]`` px adding ``glare[3]`` grey levels at
    ``glare[:2]``, clipped at 255 like a saturated sensor.

    Attributes:
        specimen: (x0, y0, x1, y1) reference rectangle of material; None: material everywhere.
        holes: discs (x, y, radius) in reference pixels with no material.
        glare: (x, y, sigma, strength) in image pixels, or None.
        background: grey level of what is not material.
    """

    specimen: tuple[float, float, float, float] | None = None
    holes: tuple[tuple[float, float, float], ...] = ()
    glare: tuple[float, float, float, float] | None = None
    background: float = 15.0

    def material(self, x: np.ndarray, y: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """True at reference points (x, y) on material at least ``margin`` px from its edges."""
        x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
        inside = np.ones(np.broadcast(x, y).shape, bool)
        if self.specimen is not None:
            x0, y0, x1, y1 = self.specimen
            inside &= (x >= x0 + margin) & (x <= x1 - margin) & (y >= y0 + margin) & (y <= y1 - margin)
        for hx, hy, radius in self.holes:
            inside &= (x - hx) ** 2 + (y - hy) ** 2 > (radius + margin) ** 2
        return inside

    def glare_light(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Grey levels the glare adds at image points (x, y) (0 without glare)."""
        if self.glare is None:
            return np.zeros(np.broadcast(x, y).shape)
        gx, gy, sigma, strength = self.glare
        return strength * np.exp(-0.5 * ((x - gx) ** 2 + (y - gy) ** 2) / sigma ** 2)


def reference_points(x: np.ndarray, y: np.ndarray, displacement: Displacement | None,
                     tol: float = 1e-8, max_iter: int = 200) -> tuple[np.ndarray, np.ndarray]:
    """Reference coordinates X with X + u(X) = x, by fixed-point iterations (arrays in pixels)."""
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    if displacement is None:
        return x, y
    rx, ry = x.copy(), y.copy()
    for _ in range(max_iter):
        ux, uy = displacement(rx, ry)
        nx, ny = x - np.asarray(ux, dtype=np.float64), y - np.asarray(uy, dtype=np.float64)
        step = max(np.max(np.abs(nx - rx)), np.max(np.abs(ny - ry)))
        rx, ry = nx, ny
        if step < tol:
            return rx, ry
    raise TrackingError("the inverse map x = X + u(X) did not converge: keep |grad u| well below 1")


def deformed_points(xy: np.ndarray, displacement: Displacement | None) -> np.ndarray:
    """Where reference points (n, 2) are seen after the displacement: X + u(X), (n, 2) pixels."""
    xy = np.asarray(xy, dtype=np.float64)
    if displacement is None:
        return xy.copy()
    ux, uy = displacement(xy[:, 0], xy[:, 1])
    return xy + np.stack([np.asarray(ux, float), np.asarray(uy, float)], axis=1)


def render_pattern(pattern, shape: tuple[int, int], displacement: Displacement | None = None, *,
                   blur_sigma: float = 1.0, noise_sigma: float = 0.0, lighting_gradient: float = 0.0,
                   levels: tuple[float, float] = (200.0, 50.0), supersample: int = 4,
                   seed: int = 0, quantize: bool = False, scene: Scene | None = None) -> np.ndarray:
    """Image (rows, cols) float64 of ``pattern`` moved by ``displacement``, 0-255 grey levels.

    The scene ``background + (ink_level - background) * ink`` (``levels``) is evaluated on a
    lattice ``supersample`` times finer than the pixels (inverse-mapped), lit by the ramp
    ``1 + lighting_gradient * ((x - xc) cos 30 deg + (y - yc) sin 30 deg) / cols``, blurred by a
    Gaussian of ``blur_sigma`` px (the optics) and averaged over each pixel's square (the sensor);
    then Gaussian noise of ``noise_sigma`` grey levels from ``seed`` is added and ``quantize``
    rounds to 8-bit integers.

    Args:
        pattern: anything with ``ink(x, y)`` (e.g. :class:`GridPattern`, :class:`SpecklePattern`).
        shape: (rows, cols).
        displacement: callable u(X, Y) -> (ux, uy) in pixels of reference coordinates, or None.
        scene: what else is in view (the specimen's extent, holes, glare; see :class:`Scene`);
            None: the pattern fills the image.
    """
    rows, cols = shape
    s = max(1, int(supersample))
    # the camera: optics blur the continuous image (done on an s-times finer lattice), then every
    # pixel integrates its square; blurring after sampling would alias the pattern's sharp edges
    fine = (np.arange(s * max(rows, cols)) + 0.5) / s - 0.5
    yy, xx = np.meshgrid(fine[:s * rows], fine[:s * cols], indexing="ij")
    rx, ry = reference_points(xx, yy, displacement)
    background, ink_level = levels
    image = background + (ink_level - background) * pattern.ink(rx, ry)
    if scene is not None:
        image = np.where(scene.material(rx, ry), image, scene.background)
        image = image + scene.glare_light(xx, yy)
    if lighting_gradient:
        ramp = ((xx - (cols - 1) / 2) * np.cos(np.pi / 6)
                + (yy - (rows - 1) / 2) * np.sin(np.pi / 6)) / cols
        image = image * (1.0 + lighting_gradient * ramp)
    if blur_sigma > 0:
        image = ndimage.gaussian_filter(image, blur_sigma * s, mode="nearest")
    image = image.reshape(rows, s, cols, s).mean(axis=(1, 3))
    if noise_sigma > 0:
        image = image + np.random.default_rng(seed).normal(0.0, noise_sigma, shape)
    if scene is not None:                      # the sensor saturates (glare)
        image = np.clip(image, 0.0, 255.0)
    if quantize:
        image = np.clip(np.rint(image), 0, 255)
    return image


def render_grid(shape: tuple[int, int], pitch_px: float = 12.0, line_width: float = 2.0,
                displacement: Displacement | None = None, blur_sigma: float = 1.0,
                noise_sigma: float = 0.0, lighting_gradient: float = 0.0, seed: int = 0, *,
                origin: tuple[float, float] | None = None, angle_deg: float = 0.0,
                bright_lines: bool = False, supersample: int = 4, quantize: bool = False,
                scene: Scene | None = None) -> np.ndarray:
    """Image (rows, cols) of a painted grid (dark lines on a light sheet, or bright lines).

    ``origin`` is a line crossing in reference pixels (default: the image centre plus a quarter
    pixel, so that crossings fall between pixel centres). See :func:`render_pattern` for the
    other arguments and :func:`grid_truth` for the true crossing positions.
    """
    pattern = grid_pattern(shape, pitch_px, line_width, origin, angle_deg)
    levels = (40.0, 210.0) if bright_lines else (200.0, 50.0)
    return render_pattern(pattern, shape, displacement, blur_sigma=blur_sigma, noise_sigma=noise_sigma,
                          lighting_gradient=lighting_gradient, levels=levels, supersample=supersample,
                          seed=seed, quantize=quantize, scene=scene)


def grid_pattern(shape, pitch_px=12.0, line_width=2.0, origin=None, angle_deg=0.0) -> GridPattern:
    """The :class:`GridPattern` that :func:`render_grid` draws with the same arguments."""
    if origin is None:
        origin = ((shape[1] - 1) / 2 + 0.25, (shape[0] - 1) / 2 + 0.25)
    return GridPattern(pitch=pitch_px, line_width=line_width, origin=tuple(origin), angle_deg=angle_deg)


def grid_truth(shape: tuple[int, int], pitch_px: float = 12.0, displacement: Displacement | None = None,
               *, origin=None, angle_deg: float = 0.0, margin: float = 0.0):
    """True crossings of :func:`render_grid`'s grid.

    Returns reference xy (n, 2), deformed xy (n, 2) and (row, col) (n, 2).

    Only crossings whose reference position lies at least ``margin`` px inside the image are listed.
    """
    pattern = grid_pattern(shape, pitch_px, 1.0, origin, angle_deg)
    rows, cols = shape
    xy, index = pattern.crossings(margin, margin, cols - 1 - margin, rows - 1 - margin)
    return xy, deformed_points(xy, displacement), index


def render_speckle(shape: tuple[int, int], speckle_sigma: float = 1.2,
                   displacement: Displacement | None = None, blur_sigma: float = 0.5,
                   noise_sigma: float = 0.0, lighting_gradient: float = 0.0, seed: int = 0, *,
                   pattern_seed: int = 0, supersample: int = 2, quantize: bool = False,
                   scene: Scene | None = None) -> np.ndarray:
    """Image (rows, cols) of a random speckle pattern (dark dots on white) moved by ``displacement``.

    Dots are Gaussians of ``speckle_sigma`` px (about 4 sigma across). The speckles come from
    ``pattern_seed`` (keep it fixed over a sequence), the noise from ``seed``.
    See :func:`render_pattern` for the other arguments.
    """
    pattern = SpecklePattern(speckle_sigma=speckle_sigma, cell=2.5 * speckle_sigma, seed=pattern_seed)
    return render_pattern(pattern, shape, displacement, blur_sigma=blur_sigma, noise_sigma=noise_sigma,
                          lighting_gradient=lighting_gradient, levels=(220.0, 30.0),
                          supersample=supersample, seed=seed, quantize=quantize, scene=scene)


def render_range(surface: Callable[[np.ndarray, np.ndarray], np.ndarray], shape: tuple[int, int], *,
                 holes=(), noise_sigma: float = 0.0, seed: int = 0) -> np.ndarray:
    """Range image (rows, cols): z = surface(x, y) at pixel centres, NaN inside the holes.

    Args:
        surface: callable z(x, y) on pixel coordinates (any length unit for z).
        holes: sequence of discs (x, y, radius) in pixels where the scanner saw nothing.
        noise_sigma: Gaussian noise on z, in z's unit.
    """
    rows, cols = shape
    yy, xx = np.mgrid[0:rows, 0:cols].astype(np.float64)
    z = np.asarray(surface(xx, yy), dtype=np.float64) * np.ones(shape)
    if noise_sigma > 0:
        z = z + np.random.default_rng(seed).normal(0.0, noise_sigma, shape)
    for hx, hy, radius in holes:
        z[(xx - hx) ** 2 + (yy - hy) ** 2 <= radius ** 2] = np.nan
    return z


def smooth_displacement(shape: tuple[int, int], stretch: float = 0.2, seed: int = 0,
                        waviness: float = 0.5) -> Displacement:
    """A random smooth displacement field u(X, Y) -> (ux, uy) in pixels, for tests.

    A stretch of ``stretch`` along x about the image centre, a seeded random lateral
    contraction and shear (up to a third and a tenth of it), plus three seeded random plane
    waves of ``waviness`` px amplitude with wavelengths of 0.5-1.5 image widths, so strains vary
    smoothly over the image.
    """
    rng = np.random.default_rng(seed)
    rows, cols = shape
    centre = np.array([(cols - 1) / 2.0, (rows - 1) / 2.0])
    gradient = np.array([[stretch, rng.uniform(-0.1, 0.1) * stretch],
                         [rng.uniform(-0.1, 0.1) * stretch, -rng.uniform(0.1, 0.33) * stretch]])
    angles = rng.uniform(0, 2 * np.pi, 3)
    lengths = rng.uniform(0.5, 1.5, 3) * cols
    waves = np.stack([np.cos(angles), np.sin(angles)], axis=1) * (2 * np.pi / lengths)[:, None]
    phases = rng.uniform(0, 2 * np.pi, 3)
    directions = rng.normal(size=(3, 2))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)

    def displacement(x, y):
        dx, dy = np.asarray(x) - centre[0], np.asarray(y) - centre[1]
        ux = gradient[0, 0] * dx + gradient[0, 1] * dy
        uy = gradient[1, 0] * dx + gradient[1, 1] * dy
        for k in range(3):
            wave = waviness * np.sin(waves[k, 0] * dx + waves[k, 1] * dy + phases[k])
            ux = ux + directions[k, 0] * wave
            uy = uy + directions[k, 1] * wave
        return ux, uy

    return displacement


def creased_displacement(shape: tuple[int, int], stretch: float = 0.12, jump: float = 0.12, seed: int = 0,
                         creases: int = 3):
    """A stretch plus ``creases`` seeded random straight creases, for tests of crossings where the
    strain changes abruptly (as at the edge of a stiff inclusion).

    Across each crease the displacement gradient jumps by ``jump`` times a random unit vector
    (its size drawn in 2/3-1 x ``jump``, the displacement stays continuous); the creases pass
    within 50 px of the image centre. The stretch is ``stretch`` along x with 30 % lateral
    contraction, about the centre.

    Returns:
        ``(displacement, distance)``: u(X, Y) -> (ux, uy) in pixels, and ``distance(xy (n, 2))``,
        each point's distance (px) to the nearest crease in the reference image.
    """
    rng = np.random.default_rng(seed)
    rows, cols = shape
    centre = np.array([(cols - 1) / 2.0, (rows - 1) / 2.0])
    angles = rng.uniform(0, np.pi, creases)
    normals = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    offsets = rng.uniform(-50, 50, creases)
    jumps = jump * rng.uniform(2 / 3, 1.0, creases) * rng.choice([-1, 1], creases)
    directions = rng.normal(size=(creases, 2))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)

    def displacement(x, y):
        dx, dy = np.asarray(x) - centre[0], np.asarray(y) - centre[1]
        ux, uy = stretch * dx, -0.3 * stretch * dy
        for n, c, j, d in zip(normals, offsets, jumps, directions):
            crease = j * np.maximum(n[0] * dx + n[1] * dy - c, 0.0)
            ux, uy = ux + crease * d[0], uy + crease * d[1]
        return ux, uy

    def distance(xy):
        return np.min(np.abs((np.asarray(xy, float) - centre) @ normals.T - offsets), axis=1)

    return displacement, distance


def scaled(displacement: Displacement, factor: float) -> Displacement:
    """The displacement field ``factor`` * u (a frame part-way through a loading sequence)."""
    return lambda x, y: tuple(factor * np.asarray(c) for c in displacement(x, y))


def clamped_displacement(clamp_x: float, strain: float, contraction: float = 0.3, centre_y: float = 0.0,
                         shift: tuple[float, float] = (0.0, 0.0)) -> Displacement:
    """A sheet clamped at x = ``clamp_x`` and stretched by ``strain`` along x (pixels in, pixels out).

    ux = strain (X - clamp_x) + shift_x, uy = -contraction strain (Y - centre_y) + shift_y: the far
    end moves most, the clamp (plus ``shift``) not at all.
    """
    def displacement(x, y):
        x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
        return strain * (x - clamp_x) + shift[0], -contraction * strain * (y - centre_y) + shift[1]

    return displacement
