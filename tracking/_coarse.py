"""A frame's global motion, estimated before any point is measured (coarse to fine).

Local measurements (a crossing's refiner, a subset's IC-GN) need a start within half a pitch or
a few pixels; a sheet can move several pitches between frames. So each frame's motion is first
estimated globally as an affine map of the reference, x' = L x + t:

- Grid: the linear part L comes from the grid itself (the lattice in the frame's spectrum against
  the reference lattice: unambiguous for any strain under 50 %), the translation t from what is
  NOT periodic: the images blurred by a Gaussian of a pitch (the grid averages out to a uniform
  grey) minus their blur at four pitches (lighting ramps go) keep the specimen's silhouette,
  its holes and edges, its far end. t is the normalised cross-correlation peak of that
  "silhouette" image against the reference's, warped by L. Where the view has no such feature
  (a grid filling the whole view) the estimate is not supported and the trackers fall back to
  temporal prediction of the translation (a motion of more than half a pitch cannot be told
  from the data); where it has one straight edge only, that fixes the translation across it.
- Speckle: the translation by the same correlation on lightly smoothed images over a search of
  a tenth of the image, then an affine refinement by ECC (OpenCV's enhanced correlation).

Local measurements start from this map plus each point's own residual from the previous frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy import ndimage

from ._errors import GridNotFoundError
from ._lattice import GridGeometry, _spectral_peaks


@dataclass(frozen=True)
class CoarseMotion:
    """Affine map of reference pixels to a frame's pixels, x' = linear @ x + offset.

    Attributes:
        linear: (2, 2).
        offset: (2,) px.
        supported: True when the frame's data determine the map (else it is the prior).
        score: the correlation (-1..1) that supported it.
    """

    linear: np.ndarray
    offset: np.ndarray
    supported: bool = False
    score: float = 0.0

    @staticmethod
    def identity() -> "CoarseMotion":
        return CoarseMotion(np.eye(2), np.zeros(2), True, 1.0)

    def apply(self, xy: np.ndarray) -> np.ndarray:
        """Mapped points, same shape as ``xy`` (..., 2); NaN stays NaN."""
        return xy @ self.linear.T + self.offset

    def extrapolated(self, before: "CoarseMotion") -> "CoarseMotion":
        """Constant-velocity guess of the next frame's map from this one and the one ``before``."""
        return CoarseMotion(2 * self.linear - before.linear, 2 * self.offset - before.offset)

    def then(self, after: "CoarseMotion") -> "CoarseMotion":
        """This map followed by ``after`` (x -> after(self(x))); supported if ``after`` is."""
        return CoarseMotion(after.linear @ self.linear, after.linear @ self.offset + after.offset,
                            after.supported, after.score)

    def since(self, before: "CoarseMotion") -> "CoarseMotion":
        """The map from ``before``'s frame to this one's (self after the inverse of ``before``)."""
        inverse = np.linalg.inv(before.linear)
        return CoarseMotion(self.linear @ inverse, self.offset - self.linear @ inverse @ before.offset,
                            self.supported, self.score)


def silhouette(image: np.ndarray, scale: float, ignore: np.ndarray | None = None) -> np.ndarray:
    """The image without its pattern: the gradient magnitude of its blur at ``scale`` (float32).

    Blurred at a pitch, a grid is a uniform grey; what is left are edges (the specimen's, a
    hole's) and lighting, whose slow ramps have a small, even gradient. ``ignore`` (e.g. glare,
    which stays in the camera's frame) is set to zero, and so is a band of two ``scale`` along
    the image's border: there the blur sees the pattern cut off by the frame (a false edge that
    stays in the camera's frame; with a grid filling the view it alone would fix a translation,
    a wrong one).
    """
    image = np.asarray(image, dtype=np.float64)
    blurred = ndimage.gaussian_filter(image, scale, mode="nearest")
    gy, gx = np.gradient(blurred)
    out = np.hypot(gx, gy)
    band = int(np.ceil(2.0 * scale))
    if 2 * band < min(out.shape):
        out[:band], out[-band:], out[:, :band], out[:, -band:] = 0.0, 0.0, 0.0, 0.0
    if ignore is not None and ignore.any():
        out[ndimage.binary_dilation(ignore, iterations=max(1, int(round(2 * scale))))] = 0.0
    return out.astype(np.float32)


def _peak(scores: np.ndarray) -> tuple[np.ndarray, float]:
    """Sub-pixel (x, y) of the maximum of a 2D score by a parabola in each axis, and its value."""
    iy, ix = np.unravel_index(int(np.argmax(scores)), scores.shape)
    out = np.array([ix, iy], dtype=np.float64)
    for axis, (i, n) in enumerate(((ix, scores.shape[1]), (iy, scores.shape[0]))):
        if 0 < i < n - 1:
            lo = scores[iy, ix - 1] if axis == 0 else scores[iy - 1, ix]
            hi = scores[iy, ix + 1] if axis == 0 else scores[iy + 1, ix]
            denom = lo - 2 * scores[iy, ix] + hi
            if denom < 0:
                out[axis] += 0.5 * (lo - hi) / denom
    return out, float(scores[iy, ix])


def translation(reference: np.ndarray, image: np.ndarray, linear: np.ndarray, prior: np.ndarray,
                search: float, step: int = 1, sharpness: float = 4.0) -> tuple[np.ndarray, float, int]:
    """The offset t of x' = linear @ x + t that best aligns ``image`` with ``reference``.

    Both are float32 (rows, cols) feature images (e.g. :func:`silhouette`). The reference is
    warped by the prior map, and the remaining shift found by normalised cross-correlation
    within ``search`` px (on images subsampled by ``step``). A direction is fixed by the data
    when the score drops by 0.01 over ``sharpness`` px along it (the curvature of the score at
    its peak); a feature that fixes one direction only (a straight edge) leaves the score flat
    along the other, and t keeps the prior's offset there.

    Returns:
        t (2,), the peak score (-1..1) and how many directions (0, 1 or 2) the data fix.
    """
    rows, cols = reference.shape
    prior = np.asarray(prior, np.float64)
    matrix = np.hstack([linear, prior.reshape(2, 1)]).astype(np.float64)
    warped = cv2.warpAffine(reference, matrix, (cols, rows), flags=cv2.INTER_LINEAR)
    if step > 1:
        warped, image = warped[::step, ::step], image[::step, ::step]
    margin = int(np.ceil(search / step))
    h, w = warped.shape
    if h <= 2 * margin + 4 or w <= 2 * margin + 4:
        margin = max(1, min(h, w) // 4)
    template = np.ascontiguousarray(warped[margin:h - margin, margin:w - margin])
    if float(template.std()) == 0.0:
        return prior, 0.0, 0
    scores = cv2.matchTemplate(np.ascontiguousarray(image), template, cv2.TM_CCOEFF_NORMED)
    where, score = _peak(scores)
    fixed = _fixed_directions(scores, np.unravel_index(int(np.argmax(scores)), scores.shape),
                              max(1, int(round(sharpness / step))))
    shift = fixed @ fixed.T @ ((where - margin) * step) if len(fixed.T) else np.zeros(2)
    return prior + shift, score, fixed.shape[1]


def _fixed_directions(scores: np.ndarray, at, reach: int) -> np.ndarray:
    """(2, k) unit directions along which the score drops by 0.01 (and by a fifth of its largest
    drop) over ``reach`` px on both sides of its peak ``at`` (row, col) (a side beyond the score's border is not looked at). The
    candidates are the principal directions of the score's curvature there (finite differences
    at ``reach``); both sides must drop, so a peak picked at the end of a plateau (an edge seen
    along its length) fixes nothing along it."""
    iy, ix = at

    def s(dy, dx):
        y, x = int(round(iy + dy)), int(round(ix + dx))
        inside = 0 <= y < scores.shape[0] and 0 <= x < scores.shape[1]
        return float(scores[y, x]) if inside else None

    r = reach
    centre = s(0, 0)

    def near(dy, dx):
        value = s(dy, dx)
        return centre if value is None else value

    hxx = (near(0, r) + near(0, -r) - 2 * centre) / r ** 2
    hyy = (near(r, 0) + near(-r, 0) - 2 * centre) / r ** 2
    hxy = (near(r, r) - near(r, -r) - near(-r, r) + near(-r, -r)) / (4 * r ** 2)
    _, vectors = np.linalg.eigh(-np.array([[hxx, hxy], [hxy, hyy]]))
    drops = []
    for v in vectors.T:
        around = [value for sign in (-1, 1) if (value := s(sign * r * v[1], sign * r * v[0])) is not None]
        drops.append(centre - max(around) if around else 0.0)
    drops = np.array(drops)
    # along a straight edge whose contrast varies (lighting) the score still drops a little: a
    # direction is fixed when its drop is also a fifth of the best direction's at least
    return vectors[:, (drops >= 0.01) & (drops >= 0.2 * drops.max())]


def frame_lattice(image: np.ndarray, geometry: GridGeometry, previous: np.ndarray,
                  material: np.ndarray | None = None) -> np.ndarray | None:
    """Linear part L (2, 2) of the frame's mean motion from its grid lattice, or None if unseen.

    The frame's two line-family wave vectors are matched to the reference's (as predicted by the
    ``previous`` L); L = K'^-1 K with K, K' the reference and frame wave vectors as rows.
    ``material``: (rows, cols) bool, where the frame's grid is expected (the reference's pattern
    mask carried by the prior map): the spectrum is taken there, as the reference's lattice was
    (a sheet's edge or the background in the spectrum pulls the peaks by a few per cent, which
    would read as strain); None or under four cells: the whole frame.
    """
    reference = np.linalg.inv(np.stack([geometry.col_step, geometry.row_step], axis=1))
    pitch = geometry.pitch
    flat = image - ndimage.gaussian_filter(image, 4.0 * pitch)
    mask = np.ones(image.shape, bool)
    if material is not None and np.count_nonzero(material) >= 4 * pitch ** 2:
        mask = material
    try:
        found = np.stack(_spectral_peaks(flat, mask, (0.5 * pitch, 2.0 * pitch)))
    except GridNotFoundError:
        return None
    predicted = reference @ np.linalg.inv(previous)
    waves = np.zeros((2, 2))
    for i, k in enumerate(predicted):
        cosine = found @ k / (np.linalg.norm(found, axis=1) * np.linalg.norm(k))
        j = int(np.argmax(np.abs(cosine)))
        waves[i] = np.sign(cosine[j]) * found[j]
    if abs(np.linalg.det(waves)) < 1e-12:
        return None
    linear = np.linalg.inv(waves) @ reference
    return linear if abs(np.linalg.det(linear) - 1.0) < 0.6 else None


LOCAL = 3.0
"""How many times its median the silhouette's 99th percentile must reach to hold edges."""

PARTIAL_EDGE = 5.0
"""How many times ``min_contrast`` the silhouette's 99th percentile must reach for a translation
fixed in one direction only to be used: a sheet's end on a dark background reaches 13 (the
foreign grid-thin-stiff set), a lighting gradient with vignetting about 1."""


def carry(prior: CoarseMotion, linear: np.ndarray, shape) -> CoarseMotion:
    """The map with the frame's own ``linear`` part and the ``prior``'s displacement at the centre
    of an image of ``shape`` (rows, cols): what is known of a frame whose translation the data
    do not fix (not supported)."""
    centre = 0.5 * np.array([shape[1] - 1, shape[0] - 1])
    return CoarseMotion(linear, prior.apply(centre) - linear @ centre)


def grid_motion(reference_features: np.ndarray, image: np.ndarray, geometry: GridGeometry,
                prior: CoarseMotion, min_contrast: float, ignore: np.ndarray | None = None,
                material: np.ndarray | None = None) -> CoarseMotion:
    """A grid frame's affine motion (see the module's notes); ``prior``: the temporal guess.

    ``reference_features`` is the reference's :func:`silhouette` at a pitch. The linear part is
    the frame's lattice wherever its spectrum shows one (else the prior is returned). The
    estimate is supported when the silhouette holds edges (its 99th percentile above
    ``min_contrast`` grey levels per px) and the frame's correlates with it (score >= 0.5, sharp
    in every direction). Where the correlation fixes one direction only (one straight edge in
    view, e.g. the sheet's end with its sides out of view; the silhouette :data:`PARTIAL_EDGE`
    times above the threshold) the translation across it is the data's and along it the
    prior's, and the map is not marked supported; with no feature the
    prior's displacement at the image centre is kept under the frame's lattice. ``material``:
    where the frame's grid is expected (see :func:`frame_lattice`).
    """
    pitch = geometry.pitch
    linear = frame_lattice(image, geometry, prior.linear, material)
    if linear is None:
        return prior
    carried = carry(prior, linear, image.shape)
    strength = float(np.percentile(reference_features, 99))
    # edges are local: a lighting ramp or vignetting (fixed to the camera) has a gradient about
    # as strong everywhere, so its 99th percentile stays within 2-3 times its median
    seen = reference_features[reference_features > 0]   # not the border band silhouette() zeroes
    if strength < min_contrast or not seen.size or strength < LOCAL * float(np.median(seen)):
        return carried
    features = silhouette(image, pitch, ignore)
    search = max(4.0 * pitch, 0.1 * max(image.shape))
    offset, score, fixed = translation(reference_features, features, linear, carried.offset, search,
                                       step=max(1, int(pitch // 3)), sharpness=0.5 * pitch)
    # one direction fixed: a straight edge, or what a lighting ramp fixed to the camera leaves;
    # trusted only from an edge well above the threshold (a lighting ramp barely passes it)
    edge = strength >= PARTIAL_EDGE * min_contrast
    if score < 0.5 or fixed == 0 or (fixed == 1 and not edge):
        return carried
    # an edge fixes the translation across it only: the map is better, but not the data's alone
    return CoarseMotion(linear, offset, fixed == 2, score)


def speckle_motion(reference: np.ndarray, image: np.ndarray, prior: CoarseMotion, search: float) -> CoarseMotion:
    """A speckle frame's affine motion: translation by correlation within ``search`` px of the
    ``prior``, then ECC affine refinement at half resolution. The whole images are used: edges
    and holes move with the material and help; unsupported (score < 0.3): the prior."""
    ref = ndimage.gaussian_filter(np.asarray(reference, np.float64), 1.5).astype(np.float32)
    cur = ndimage.gaussian_filter(np.asarray(image, np.float64), 1.5).astype(np.float32)
    offset, score, fixed = translation(ref, cur, prior.linear, prior.offset, search, step=2)
    if score < 0.3 or fixed < 2:
        return prior
    warp = np.hstack([prior.linear, offset.reshape(2, 1) / 2.0]).astype(np.float32)
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-5)
    try:
        # the map of half-resolution pixels (every second one) is x'/2 = L x/2 + t/2
        ecc, warp = cv2.findTransformECC(np.ascontiguousarray(ref[::2, ::2]), np.ascontiguousarray(cur[::2, ::2]),
                                         warp, cv2.MOTION_AFFINE, criteria, None, 5)
    except cv2.error:
        return CoarseMotion(prior.linear, offset, True, score)
    warp = warp.astype(np.float64)
    if ecc < score or abs(np.linalg.det(warp[:, :2]) - 1.0) > 0.5:
        return CoarseMotion(prior.linear, offset, True, score)
    return CoarseMotion(warp[:, :2], 2.0 * warp[:, 2], True, float(ecc))
