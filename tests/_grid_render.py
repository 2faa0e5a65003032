"""An independent renderer of painted-grid images with exact truth, for the grid conventions sweep.

Written apart from ``tracking/_synthetic.py`` on purpose (its own line profile, deformation,
camera and sheet), so that the tracker is checked on images it was not shaped by:

- paint: two families of lines with a Gaussian profile (``width`` the full width at half depth,
  any pitch, angle and phase), multiplicative (ink darkens the sheet by ``1 - depth * profile``;
  where lines cross the darkening compounds), or light lines on a dark sheet;
- deformation: a smooth displacement field u(X) (a stretch, a shear, a bulge) applied by
  inverse mapping: every pixel x of a deformed frame is traced back to its material point X
  with x = X + u(X) by Newton's iteration on the exact Jacobian (to 1e-10 px);
- the sheet: a rectangle of material (the region beyond it is a background: dark, light,
  textured or noisy), optionally running out of the view;
- the camera: supersampling over each pixel's square (box filter), Gaussian blur, a lighting
  gradient and vignetting (fixed in the camera frame), Gaussian noise, 8-bit rounding and
  optionally JPEG compression.

Truth: the crossings of the painted lattice in the reference frame (material points, pixel
centres at integer coordinates) and their exact positions x = X + u(X) in every frame.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import cv2
import numpy as np
from scipy import ndimage


@dataclass(frozen=True)
class Convention:
    """One drawn look of a painted grid and its camera (pixels, grey levels 0-255).

    Attributes:
        pitch: distance between neighbouring lines (px, reference frame).
        width: line full width at half depth (px, before camera blur).
        angle: rotation of the grid (degrees).
        phase: (2,) offset of a crossing from the image origin (px).
        dark_lines: dark lines on a light sheet, else light lines on a dark sheet.
        sheet, contrast: sheet grey level and the lines' depth (grey levels).
        background: "dark", "light", "texture" or "noise": what lies beyond the sheet.
        sheet_box: (x0, y0, x1, y1) of the sheet in the reference frame (px); None fills the view.
        blur: camera Gaussian blur (px).
        gradient: lighting change across the view (fraction of the sheet level).
        vignetting: fall of light at the view's corners (fraction).
        noise: Gaussian noise (grey levels RMS).
        jpeg: JPEG quality (None: lossless).
        strain: largest stretch of the motion (fraction); shear and bulge scale with it.
        anchor: (x, y) of the stretch's fixed point as fractions of the view (a clamp: x < 0).
        shape: (rows, cols) of the images.
        supersample: sub-pixels per pixel side.
    """

    pitch: float = 12.0
    width: float = 2.0
    angle: float = 0.0
    phase: tuple[float, float] = (0.0, 0.0)
    dark_lines: bool = True
    sheet: float = 180.0
    contrast: float = 120.0
    background: str = "dark"
    sheet_box: tuple[float, float, float, float] | None = None
    blur: float = 0.0
    gradient: float = 0.0
    vignetting: float = 0.0
    noise: float = 0.0
    jpeg: int | None = None
    strain: float = 0.05
    shape: tuple[int, int] = (200, 260)
    supersample: int = 3
    seed: int = 0
    anchor: tuple[float, float] = (0.5, 0.5)

    def with_(self, **changes) -> "Convention":
        return replace(self, **changes)


def displacement(c: Convention, X: np.ndarray, Y: np.ndarray, frame: float):
    """u(X) (px) of ``frame`` (0 the reference, 1 the full motion) and its Jacobian (4 arrays).

    A stretch along x about the ``anchor`` with Poisson contraction, a shear and a smooth bulge
    (a Gaussian bump of displacement a third of the view wide at the centre), scaled by ``strain``.
    """
    rows, cols = c.shape
    ax, ay = c.anchor[0] * (cols - 1), c.anchor[1] * (rows - 1)
    cx, cy = 0.5 * (cols - 1), 0.5 * (rows - 1)
    e = c.strain * frame
    ex, ey, g = e, -0.35 * e, 0.3 * e
    r = 0.3 * min(rows, cols)
    bump = np.exp(-((X - cx) ** 2 + (Y - cy) ** 2) / (2 * r ** 2))
    amp = 0.15 * e * r
    ux = ex * (X - ax) + g * (Y - ay) + amp * bump + 1.3 * frame
    uy = ey * (Y - ay) + 0.5 * amp * bump - 0.7 * frame
    dbx, dby = -bump * (X - cx) / r ** 2, -bump * (Y - cy) / r ** 2
    return ux, uy, ex + amp * dbx, g + amp * dby, 0.5 * amp * dbx, ey + 0.5 * amp * dby


def material_points(c: Convention, x: np.ndarray, y: np.ndarray, frame: float):
    """X with X + u(X) = x by Newton's iteration (exact Jacobian), to 1e-10 px."""
    X, Y = x.copy(), y.copy()
    for _ in range(30):
        ux, uy, a, b, cc, d = displacement(c, X, Y, frame)
        fx, fy = X + ux - x, Y + uy - y
        j11, j12, j21, j22 = 1 + a, b, cc, 1 + d
        det = j11 * j22 - j12 * j21
        dX, dY = (j22 * fx - j12 * fy) / det, (-j21 * fx + j11 * fy) / det
        X, Y = X - dX, Y - dY
        if max(np.abs(dX).max(), np.abs(dY).max()) < 1e-10:
            break
    return X, Y


def _lattice_coords(c: Convention, X, Y):
    t = np.radians(c.angle)
    dx, dy = X - c.phase[0], Y - c.phase[1]
    return np.cos(t) * dx + np.sin(t) * dy, -np.sin(t) * dx + np.cos(t) * dy


def _profile(c: Convention, s):
    d = s - c.pitch * np.round(s / c.pitch)
    sigma = c.width / (2.0 * np.sqrt(2.0 * np.log(2.0)))
    return np.exp(-0.5 * (d / sigma) ** 2)


def paint(c: Convention, X, Y):
    """Reflectance of the material at X (grey levels, before lighting): sheet and lines."""
    s, t = _lattice_coords(c, X, Y)
    ink = 1.0 - (1.0 - _profile(c, s)) * (1.0 - _profile(c, t))   # crossing darkens once, not twice
    if c.dark_lines:
        return c.sheet - c.contrast * ink
    return c.sheet + c.contrast * ink


def _background(c: Convention, x, y, rng):
    kind = c.background
    if kind == "dark":
        return np.full(x.shape, 25.0)
    if kind == "light":
        return np.full(x.shape, 235.0)
    if kind == "texture":   # a fixed, camera-frame clutter of blobs (smoothed noise, not periodic)
        field = ndimage.gaussian_filter(np.random.default_rng(7).standard_normal((64, 64)), 2.0)
        field = field / field.std()
        ix = (np.floor(x / 3.0).astype(int)) % 64
        iy = (np.floor(y / 3.0).astype(int)) % 64
        return 110.0 + 40.0 * field[iy, ix]
    return 128.0 + 60.0 * rng.standard_normal(x.shape)


def render(c: Convention, frame: float, rng: np.random.Generator) -> np.ndarray:
    """The (rows, cols) uint8 image of ``frame`` (0 reference .. 1 full motion)."""
    rows, cols = c.shape
    n = c.supersample
    sub = (np.arange(n) + 0.5) / n - 0.5
    y = (np.arange(rows)[:, None] + sub[None, :]).ravel()
    x = (np.arange(cols)[:, None] + sub[None, :]).ravel()
    xx, yy = np.meshgrid(x, y)
    X, Y = material_points(c, xx, yy, frame)
    value = paint(c, X, Y)
    if c.sheet_box is not None:
        x0, y0, x1, y1 = c.sheet_box
        off = (X < x0) | (X > x1) | (Y < y0) | (Y > y1)
        value = np.where(off, _background(c, xx, yy, rng), value)
    image = value.reshape(rows, n, cols, n).mean(axis=(1, 3))
    if c.blur > 0:
        image = ndimage.gaussian_filter(image, c.blur, mode="nearest")
    gy, gx = np.mgrid[0:rows, 0:cols].astype(np.float64)
    u, v = (gx - 0.5 * (cols - 1)) / cols, (gy - 0.5 * (rows - 1)) / rows
    light = (1.0 + c.gradient * (0.8 * u + 0.6 * v)) * (1.0 - c.vignetting * 2.0 * (u ** 2 + v ** 2))
    image = image * light + c.noise * rng.standard_normal(image.shape)
    image = np.clip(np.rint(image), 0, 255).astype(np.uint8)
    if c.jpeg is not None:
        ok, data = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, int(c.jpeg)])
        image = cv2.imdecode(data, cv2.IMREAD_GRAYSCALE)
    return image


def crossings(c: Convention, margin: float | None = None) -> np.ndarray:
    """(n, 2) painted crossings (reference, px) on the sheet and at least ``margin`` px (default:
    half a pitch) inside the view and the sheet."""
    rows, cols = c.shape
    margin = 0.5 * c.pitch if margin is None else margin
    span = 2 * int(np.hypot(rows, cols) / c.pitch) + 4
    k = np.arange(-span, span + 1) * c.pitch
    s, t = np.meshgrid(k, k)
    a = np.radians(c.angle)
    X = c.phase[0] + np.cos(a) * s - np.sin(a) * t
    Y = c.phase[1] + np.sin(a) * s + np.cos(a) * t
    box = (0, 0, cols - 1, rows - 1) if c.sheet_box is None else c.sheet_box
    x0, y0 = max(box[0], 0) + margin, max(box[1], 0) + margin
    x1, y1 = min(box[2], cols - 1) - margin, min(box[3], rows - 1) - margin
    keep = (X >= x0) & (X <= x1) & (Y >= y0) & (Y <= y1)
    return np.stack([X[keep], Y[keep]], axis=1)


def sequence(c: Convention, frames: int = 3):
    """Images (frames, rows, cols) uint8 from the reference to the full motion, the reference
    crossings (n, 2) and their exact positions (frames, n, 2)."""
    rng = np.random.default_rng(c.seed)
    times = np.linspace(0.0, 1.0, frames)
    images = np.stack([render(c, f, rng) for f in times])
    ref = crossings(c)
    truth = []
    for f in times:
        ux, uy, *_ = displacement(c, ref[:, 0], ref[:, 1], f)
        truth.append(ref + np.stack([ux, uy], axis=1))
    return images, ref, np.stack(truth)


def draw(rng: np.random.Generator, shape=(200, 260)) -> Convention:
    """A convention drawn at random from the ranges the grid tracker promises to hold on."""
    pitch = float(rng.uniform(6.0, 60.0))
    rows = int(max(shape[0], 6 * pitch))
    cols = int(max(shape[1], 8 * pitch))
    width = float(rng.uniform(1.0, min(8.0, 0.3 * pitch)))
    dark = bool(rng.random() < 0.6)
    contrast = float(rng.choice([20.0, 40.0, 80.0, 140.0]))
    sheet = float(rng.uniform(140.0, 220.0)) if dark else float(rng.uniform(20.0, 70.0))
    box = None
    if rng.random() < 0.5:   # the sheet ends inside the view on one to three sides, runs out on the others
        ends = rng.permutation(3)[: int(rng.integers(1, 4))]
        x0, x1, y1 = -1e9, 1e9, 1e9
        if 0 in ends:
            x0 = float(rng.uniform(0.1, 0.25) * cols)
        if 1 in ends:
            x1 = float(rng.uniform(0.75, 0.9) * cols)
        if 2 in ends:
            y1 = float(rng.uniform(0.7, 0.9) * rows)
        box = (x0, -1e9, x1, y1)
    return Convention(
        pitch=pitch, width=width, angle=float(rng.uniform(-8.0, 8.0)),
        phase=(float(rng.uniform(0, pitch)), float(rng.uniform(0, pitch))), dark_lines=dark,
        sheet=sheet, contrast=contrast, background=str(rng.choice(["dark", "light", "texture", "noise"])),
        sheet_box=box, blur=float(rng.choice([0.0, 0.6, 1.2])), gradient=float(rng.uniform(0.0, 0.4)),
        vignetting=float(rng.uniform(0.0, 0.3)), noise=float(rng.choice([0.0, 1.0, 2.0])),
        jpeg=int(70) if rng.random() < 0.3 else None, strain=float(rng.uniform(0.02, 0.12)),
        shape=(rows, cols), seed=int(rng.integers(1 << 30)))


def score(c: Convention, frames: int = 3, tracker=None) -> dict:
    """Track ``sequence(c)`` with the grid tracker (default settings) and score it against the
    exact truth: coverage (share of the visible crossings, ``crossings(c)``, tracked in the
    reference: a tracked point within a quarter pitch), displacement RMS (px, over the matched
    crossings and frames after the reference), point-frames lost, seconds. A tracking error is
    a row with its message."""
    import time

    from scipy.spatial import cKDTree

    from tracking import GridTracker, TrackingError

    images, ref, truth = sequence(c, frames)
    start = time.perf_counter()
    try:
        tracks = (tracker or GridTracker()).track(images.astype(np.float64))
    except TrackingError as e:
        return {"coverage": 0.0, "rms_px": float("inf"), "lost": None, "seconds": time.perf_counter() - start,
                "error": str(e), "visible": len(ref)}
    seconds = time.perf_counter() - start
    got = tracks.reference
    seen = np.isfinite(got[:, 0])
    distance, nearest = cKDTree(ref).query(np.where(seen[:, None], got, -1e6))
    match = seen & (distance < 0.25 * c.pitch)
    coverage = len(set(nearest[match])) / max(len(ref), 1)
    errors, lost = [], 0
    for k in range(1, frames):
        moved = tracks.positions[k] - got
        true = truth[k][nearest] - ref[nearest]
        ok = match & np.isfinite(moved[:, 0])
        lost += int(np.count_nonzero(match & ~ok))
        errors.append(np.linalg.norm(moved[ok] - true[ok], axis=1))
    errors = np.concatenate(errors) if errors else np.zeros(0)
    rms = float(np.sqrt(np.mean(errors ** 2))) if errors.size else float("inf")
    return {"coverage": float(coverage), "rms_px": rms, "max_px": float(errors.max()) if errors.size else float("inf"),
            "lost": lost, "seconds": seconds, "error": None, "visible": len(ref)}
