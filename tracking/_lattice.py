"""The grid's geometry from the reference image: lattice vectors, line polarity and width.

The two line families show as the two strongest non-parallel peaks of the image's power
spectrum; their wave vectors give the crossing lattice (pitch and orientation). Folding the
image over one family's phase gives the mean line profile: its narrow extreme tells the
polarity (dark lines on a light sheet or the reverse) and its width the line width.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from ._errors import GridNotFoundError


@dataclass(frozen=True)
class GridGeometry:
    """Lattice of grid crossings and the look of its lines (reference image, pixels).

    Attributes:
        col_step: (2,) vector from a crossing to the next one in the same row (towards +x).
        row_step: (2,) vector from a crossing to the next one in the same column (towards +y).
        dark_lines: True for dark lines on a light background.
        line_width: full width at half depth of the mean line profile, blur included (px).
    """

    col_step: np.ndarray
    row_step: np.ndarray
    dark_lines: bool
    line_width: float

    @property
    def pitch(self) -> float:
        """Mean distance between neighbouring crossings (px)."""
        return 0.5 * float(np.linalg.norm(self.col_step) + np.linalg.norm(self.row_step))


def _spectral_peaks(image: np.ndarray, mask: np.ndarray, pitch_range) -> tuple[np.ndarray, np.ndarray]:
    rows, cols = np.nonzero(mask)
    r0, r1, c0, c1 = rows.min(), rows.max() + 1, cols.min(), cols.max() + 1
    if min(r1 - r0, c1 - c0) < 2 * pitch_range[0]:
        raise GridNotFoundError("grid not found at the lattice stage: the region of interest is too small "
                                f"to hold two pitches of {pitch_range[0]:g} px; enlarge the ROI (--roi)", "lattice")
    patch = image[r0:r1, c0:c1]
    inside = mask[r0:r1, c0:c1]
    fy = np.fft.fftfreq(patch.shape[0])[:, None] * np.ones(patch.shape)
    fx = np.fft.fftfreq(patch.shape[1])[None, :] * np.ones(patch.shape)
    radius = np.hypot(fx, fy)
    centred = np.where(inside, patch - patch[inside].mean(), 0.0)
    window = np.outer(np.hanning(patch.shape[0]), np.hanning(patch.shape[1]))
    power = np.abs(np.fft.fft2(centred * window)) ** 2
    # the peaks' bins are picked on a whitened spectrum with the edges' weight clipped
    whitened = _clipped_gradient_power(patch, inside)
    clipped = whitened / np.maximum((2.0 * np.pi * radius) ** 2, 1e-300)
    usable = (radius >= 1.0 / pitch_range[1]) & (radius <= 1.0 / pitch_range[0])
    usable &= (fx > 0) | ((fx == 0) & (fy > 0))
    if not usable.any():
        raise GridNotFoundError(f"grid not found at the lattice stage: no frequencies of the image fit the pitch "
                                f"range {pitch_range[0]:g}-{pitch_range[1]:g} px; widen it (GridTracker.pitch_range)",
                                "lattice")
    score = np.where(usable, whitened, 0.0)
    first = np.unravel_index(np.argmax(score), score.shape)
    k1 = np.array([fx[first], fy[first]])
    angle = np.abs(fx * k1[1] - fy * k1[0]) / (radius * np.linalg.norm(k1) + 1e-300)
    score2 = np.where(usable & (angle > np.sin(np.radians(30))), whitened, 0.0)
    second = np.unravel_index(np.argmax(score2), score2.shape)
    background = np.median(clipped[usable])

    def fundamental(peak):
        # clipping gives a thin line's harmonics more power still: the plain spectrum's
        # fundamental is taken too where the clipped spectrum shows a clear peak there
        found = _fundamental(clipped, peak, fx, fy, usable)
        if found == peak:
            plain = _fundamental(power, peak, fx, fy, usable)
            found = plain if clipped[plain] >= 20.0 * background else found
        return found

    first, second = fundamental(first), fundamental(second)
    for peak in (first, second):
        if clipped[peak] < 20.0 * background:
            raise GridNotFoundError(
                f"grid not found at the lattice stage: the image spectrum shows no two clear line "
                f"families with a pitch of {pitch_range[0]:g}-{pitch_range[1]:g} px; try the grid's pitch "
                "range (GridTracker.pitch_range; nonrigid track --option 'pitch_range=(LO,HI)' in px), a "
                "region of interest on the grid alone (--roi), and check that the grid is in focus", "lattice")
    return _refined_frequency(power, first, fx, fy), _refined_frequency(power, second, fx, fy)


def _clipped_gradient_power(patch: np.ndarray, inside: np.ndarray) -> np.ndarray:
    """The whitened power spectrum of ``patch`` (its gradient's power, |2 pi f|^2 times the
    image's) with the gradient's magnitude clipped at its 90th percentile inside the mask.

    Whitening keeps a grid's peaks against the 1/f^2 fall of an edge's power (an edge in view,
    the specimen's or a hole's), but a step edge's whitened spectrum is a flat ridge along its
    normal, and a step of the full sheet-to-background contrast at low frequency can still beat
    or displace a faint grid's peak lying within a bin of that ridge (a grid turned by a few
    degrees from the edge). Clipped, the step's gradient weighs as much as one grid line, a
    family's lines add coherently, so the grid's peaks stand out again; clipping is pointwise,
    so a family's peak stays where it is (its harmonics gain power, handled by
    :func:`_fundamental`).
    """
    gy, gx = np.gradient(patch)
    magnitude = np.hypot(gx, gy)
    top = np.percentile(magnitude[inside], 90) if inside.any() else 0.0
    shrink = np.where(inside, np.minimum(1.0, top / np.maximum(magnitude, 1e-300)), 0.0)
    window = np.outer(np.hanning(patch.shape[0]), np.hanning(patch.shape[1])) * shrink
    return np.abs(np.fft.fft2(gx * window)) ** 2 + np.abs(np.fft.fft2(gy * window)) ** 2


def _fundamental(power, peak, fx, fy, usable):
    """The line family's fundamental for a spectral ``peak``: the lowest sub-multiple
    ``peak / n`` in the usable band whose whole harmonic series is there, else ``peak``.

    Whitening favours a thin line's harmonics (a Gaussian line of sigma 0.7 px at a 24 px pitch
    has nearly equal power up to its fifth harmonic, whose whitened power is then 25 times the
    fundamental's). ``peak / n`` is the fundamental when it and each multiple ``m peak / n``
    (m < n) hold, within a bin, a tenth of the picked peak's power and 20 times the band's
    median: a line's harmonics below the whitened maximum are at least as strong as it (Gaussian
    or blurred lines; a box profile's notches keep a quarter), while the side lobes of an edge's
    spectrum (a sheet's end in view) fall as 1/f^2 and miss at the higher multiples. The
    candidate must also be the largest power of the 5 x 5 bins around it.
    """
    shape = power.shape
    background = np.median(power[usable])
    radius = np.hypot(fx, fy)
    frequency = radius[peak]
    low = np.min(radius[usable])

    def strongest(f_y, f_x, reach):
        rows = [(int(round(f_y * shape[0])) + d) % shape[0] for d in range(-reach, reach + 1)]
        cols = [(int(round(f_x * shape[1])) + d) % shape[1] for d in range(-reach, reach + 1)]
        block = power[np.ix_(rows, cols)]
        i, j = np.unravel_index(int(np.argmax(block)), block.shape)
        return float(block[i, j]), (rows[i], cols[j])

    floor = max(0.1 * power[peak], 20.0 * background)
    for n in range(int(frequency / max(low, 1e-12)), 1, -1):
        f_y, f_x = fy[peak] / n, fx[peak] / n
        value, where = strongest(f_y, f_x, 1)
        # the band's radius, not its half plane: the conjugate bin holds the same power
        if radius[where] < low or value < floor or value < strongest(f_y, f_x, 2)[0]:
            continue
        if all(strongest(m * f_y, m * f_x, 1)[0] >= floor for m in range(2, n)):
            return where
    return peak


def _refined_frequency(power, peak, fx, fy) -> np.ndarray:
    """Sub-bin peak position by a parabola through the log power in each axis."""
    log = np.log(power + 1e-300)
    shape = power.shape
    out = np.array([fx[peak], fy[peak]])
    for axis, step in ((1, 1.0 / shape[1]), (0, 1.0 / shape[0])):
        lo, hi = list(peak), list(peak)
        lo[axis] = (peak[axis] - 1) % shape[axis]
        hi[axis] = (peak[axis] + 1) % shape[axis]
        a, b, c = log[tuple(lo)], log[peak], log[tuple(hi)]
        denom = a - 2 * b + c
        if denom < 0:
            out[0 if axis == 1 else 1] += step * 0.5 * (a - c) / denom
    return out


def _folded_profile(image, mask, wave, bins) -> np.ndarray:
    rows, cols = np.nonzero(mask)
    phase = (wave[0] * cols + wave[1] * rows) % 1.0
    index = np.minimum((phase * bins).astype(int), bins - 1)
    total = np.bincount(index, weights=image[rows, cols], minlength=bins)
    count = np.bincount(index, minlength=bins)
    filled = count > 0
    centres = (np.arange(bins) + 0.5) / bins
    # an axis-aligned grid samples few phases: fill the empty bins periodically
    return np.interp(centres, centres[filled], total[filled] / count[filled], period=1.0)


def grid_geometry(image: np.ndarray, mask: np.ndarray, pitch_range=(4.0, 80.0),
                  dark_lines: bool | None = None) -> GridGeometry:
    """Measure the grid lattice and line appearance in ``image`` (rows, cols) inside ``mask``.

    Args:
        pitch_range: (min, max) grid pitch in pixels to look for.
        dark_lines: force the polarity; None detects it.

    Raises:
        GridNotFoundError: no two line families in the spectrum.
    """
    flat = image - ndimage.gaussian_filter(image, 2.0 * pitch_range[1])
    k1, k2 = _spectral_peaks(flat, mask, pitch_range)
    lattice = np.linalg.inv(np.stack([k1, k2]))  # columns a1, a2 with k_i . a_j = delta_ij
    steps = [lattice[:, 0], lattice[:, 1]]
    col = int(np.argmax([abs(s[0]) / np.linalg.norm(s) for s in steps]))
    col_step, row_step = steps[col], steps[1 - col]
    col_step = col_step if col_step[0] >= 0 else -col_step
    row_step = row_step if row_step[1] >= 0 else -row_step
    waves = (k1, k2)
    pitch = float(np.mean([1.0 / np.linalg.norm(k) for k in waves]))
    bins = max(8, int(round(pitch)))
    profiles = [_folded_profile(flat, mask, k, bins) for k in waves]
    # centre each family's line in its profile before averaging the two
    profile = np.mean([np.roll(p, bins // 2 - int(np.argmax(np.abs(p - np.median(p)))))
                       for p in profiles], axis=0)
    base = np.median(profile)
    if dark_lines is None:
        dark_lines = bool(base > 0.5 * (profile.min() + profile.max()))
    depth = (base - profile) if dark_lines else (profile - base)
    # width at half depth, with linear interpolation of the two crossings around the extreme
    fine = np.interp(np.arange(bins * 16) / 16.0, np.arange(bins), depth, period=bins)
    line_width = float(np.count_nonzero(fine > 0.5 * depth.max())) / 16.0 * pitch / bins
    return GridGeometry(col_step=col_step, row_step=row_step, dark_lines=dark_lines,
                        line_width=max(line_width, 1.0))


def ink_image(image: np.ndarray, geometry: GridGeometry, mask: np.ndarray | None = None) -> np.ndarray:
    """Lines as positive ridges: background removed, polarity set, local contrast normalised.

    The background (the sheet's level under the lines) is the mean over a box of one pitch,
    which holds whole periods of both line families whatever their phase, smoothed by a
    Gaussian of half a pitch: its error on a curved lighting (vignetting) is (1/24 + 1/8)
    pitch^2 times the level's Laplacian, against 1.125 pitch^2 for a Gaussian of 1.5 pitches
    (at a 50 px pitch and 20 % vignetting that is 1.4 against 9.5 grey levels: as much as a
    faint grid's contrast). The contrast is the mean absolute ink over 1.5 pitches.

    With a ``mask`` of the material (True where the grid is), both are local means over the
    material only (normalised convolution), so crossings next to a hole or the specimen's edge
    keep their ink instead of sinking under the dark side's mean; off the mask the ink is 0.
    """
    pitch = geometry.pitch
    box = max(3, int(round(pitch)))

    def smooth(values, sigma, size):
        values = ndimage.uniform_filter(values, size, mode="nearest") if size else values
        return ndimage.gaussian_filter(values, sigma, mode="nearest")

    def local_mean(values, sigma, size=0):
        if mask is None:
            return smooth(values, sigma, size)
        weight = smooth(mask.astype(np.float64), sigma, size)
        return smooth(np.where(mask, values, 0.0), sigma, size) / np.maximum(weight, 1e-3)

    background = local_mean(image, 0.5 * pitch, box)
    ink = (background - image) if geometry.dark_lines else (image - background)
    if mask is not None:   # off the material (a hole, the background) there is no ink to follow
        ink = np.where(mask, ink, 0.0)
    contrast = local_mean(np.abs(ink), 1.5 * pitch)
    return ink / (contrast + 1e-6 * (np.abs(contrast).max() + 1e-300))
