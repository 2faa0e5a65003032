"""Loading images and checking the image stack and the region of interest."""

from __future__ import annotations

import glob
import re
import warnings
from pathlib import Path
from typing import Sequence

import numpy as np

from ._errors import ImageError, RoiError

IMAGE_SUFFIXES = (".tif", ".tiff", ".png", ".jpg", ".jpeg", ".bmp", ".pgm", ".ppm")


def natural_key(path: str | Path) -> list:
    """Sort key that orders names as people count: frame_2 before frame_10."""
    return [int(part) if part.isdigit() else part.lower() for part in re.split(r"(\d+)", str(path))]


def image_paths(sources: str | Path | Sequence[str | Path]) -> list[Path]:
    """The image files that ``sources`` name, in natural order within each source.

    A source is a file, a folder (its image files: ``IMAGE_SUFFIXES``) or a glob pattern
    (``"frames/img_*.tif"``); several sources keep the order given. Raises :class:`ImageError`
    naming a source that matches no image.
    """
    return file_paths(sources, IMAGE_SUFFIXES, "image")


def file_paths(sources: str | Path | Sequence[str | Path], suffixes: Sequence[str], what: str) -> list[Path]:
    """The files ``sources`` name (files, folders of files with one of ``suffixes``, glob patterns),
    in natural order within each source; ``what`` names them in the errors (e.g. "range image")."""
    if isinstance(sources, (str, Path)):
        sources = [sources]
    out: list[Path] = []
    for source in sources:
        path = Path(source)
        if path.is_dir():
            found = sorted((p for p in path.iterdir() if p.suffix.lower() in suffixes), key=natural_key)
            if not found:
                raise ImageError(f"folder {path} holds no {what} files ({', '.join(suffixes)})")
        elif path.is_file():
            found = [path]
        elif any(c in str(source) for c in "*?["):
            found = sorted((Path(p) for p in glob.glob(str(source)) if Path(p).is_file()), key=natural_key)
            if not found:
                raise ImageError(f"the pattern {source!r} matches no file")
        else:
            raise ImageError(f"{what} file not found: {path}")
        out.extend(found)
    return out


def load_images(paths: str | Path | Sequence[str | Path]) -> np.ndarray:
    """Read images (TIFF, PNG, ...) into a float64 grey stack, (n_frames, rows, cols).

    ``paths``: files, folders or glob patterns (see :func:`image_paths`: natural order, so
    frame_2 comes before frame_10). A multi-page TIFF gives one frame per page. Grey values keep
    the file's scale (0-255 for 8-bit, 0-65535 for 16-bit); colour images are converted with the
    ITU-R 601 luma weights, an alpha channel is ignored.
    """
    frames = []
    for path in image_paths(paths):
        frames.extend(_read_frames(path))
    return as_stack(frames)


def _read_frames(path: Path) -> list[np.ndarray]:
    """The grey frames of one file: one, or one per page of a multi-page TIFF."""
    import cv2  # imported here: only loading needs it

    if path.suffix.lower() in (".tif", ".tiff"):
        try:
            import tifffile

            with tifffile.TiffFile(str(path)) as tif:
                pages = len(tif.pages)
                data = np.asarray(tif.asarray())
        except Exception:  # noqa: BLE001 - no tifffile, or not a TIFF it reads: the readers below report
            data, pages = None, 0
        # frames are pages, or the first axis of a 3D page that is not colour (rows, cols, 2, 3 or 4)
        if data is not None and (pages > 1 or (data.ndim == 3 and data.shape[-1] not in (2, 3, 4))):
            return [_to_grey(frame, bgr=False) for frame in data]
    image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if image is not None:
        return [_to_grey(np.asarray(image), bgr=True)]
    try:
        import skimage.io

        with warnings.catch_warnings():  # imageio tries its legacy plugins (DICOM's is deprecated)
            warnings.simplefilter("ignore", DeprecationWarning)
            image = skimage.io.imread(str(path))
    except Exception as error:  # noqa: BLE001 - report any reader failure the same way
        if path.stat().st_size == 0:
            raise ImageError(f"image file {path} is empty (0 bytes); export the frame again") from None
        first = next((line.strip() for line in str(error).splitlines() if line.strip()), type(error).__name__)
        raise ImageError(f"cannot read image {path}: {first}; give a TIFF, PNG, JPEG or BMP file that "
                         "opens in an image viewer") from error
    return [_to_grey(np.asarray(image), bgr=False)]


def _to_grey(image: np.ndarray, bgr: bool) -> np.ndarray:
    image = np.asarray(image, dtype=np.float64)
    if image.ndim == 2:
        return image
    if image.ndim == 3 and image.shape[2] in (2, 3, 4):
        if image.shape[2] == 2:  # grey + alpha
            return image[..., 0]
        rgb = image[..., :3][..., ::-1] if bgr else image[..., :3]
        return rgb @ np.array([0.299, 0.587, 0.114])
    raise ImageError(f"cannot make a grey image from an array of shape {image.shape}")


def as_stack(images) -> np.ndarray:
    """Check images and return them as one float64 array (n_frames, rows, cols).

    Accepts a sequence of 2D arrays, a 3D array, or what :func:`load_images` reads (files,
    folders, glob patterns). Raises :class:`ImageError` for
    NaN/inf values, unequal shapes, fewer than one frame or images smaller than 8 x 8 pixels.
    """
    if isinstance(images, (str, Path)):
        return load_images(images)  # a folder, a glob pattern or one (multi-page) file
    if isinstance(images, np.ndarray) and images.ndim == 3:
        frames = list(images)
    else:
        frames = list(images)
    if not frames:
        raise ImageError("no images given")
    if all(isinstance(frame, (str, Path)) for frame in frames):
        return load_images(frames)
    stack = []
    for k, frame in enumerate(frames):
        frame = np.asarray(frame)
        if frame.ndim != 2:
            if frame.ndim == 3:
                frame = _to_grey(frame, bgr=False)
            else:
                raise ImageError(f"image {k} has shape {frame.shape}; expected (rows, cols)")
        if not np.all(np.isfinite(frame)):
            raise ImageError(f"image {k} contains NaN or infinite values; "
                             "tracking needs finite grey values")
        stack.append(np.asarray(frame, dtype=np.float64))
    shapes = {frame.shape for frame in stack}
    if len(shapes) != 1:
        raise ImageError(f"all images must have the same shape, got {sorted(shapes)}")
    if min(stack[0].shape) < 8:
        raise ImageError(f"images of shape {stack[0].shape} are too small to track anything")
    return np.stack(stack)


def roi_mask(roi, shape: tuple[int, int]) -> np.ndarray:
    """Boolean mask (rows, cols) of the region of interest.

    Args:
        roi: None (whole image), (x0, y0, x1, y1) in pixels of the first image (x = column,
            y = row, x1/y1 exclusive), or a boolean/0-1 mask of the image's shape.
        shape: (rows, cols) of the images.
    """
    rows, cols = shape
    if roi is None:
        return np.ones(shape, dtype=bool)
    array = np.asarray(roi)
    if array.ndim == 2:
        if array.shape != tuple(shape):
            raise RoiError(f"ROI mask has shape {array.shape} but the images are {tuple(shape)}")
        mask = array > 0
        if not mask.any():
            raise RoiError("ROI mask is empty")
        return mask
    if array.shape != (4,):
        raise RoiError(f"ROI must be (x0, y0, x1, y1) or a mask of the image shape, got {roi!r}")
    x0, y0, x1, y1 = (float(v) for v in array)
    if not (x1 > x0 and y1 > y0):
        raise RoiError(f"ROI (x0, y0, x1, y1) = {tuple(array)} needs x1 > x0 and y1 > y0")
    if x0 < 0 or y0 < 0 or x1 > cols or y1 > rows:
        raise RoiError(f"ROI (x0, y0, x1, y1) = {tuple(array)} is outside the image of "
                       f"{cols} x {rows} pixels (x < {cols}, y < {rows})")
    mask = np.zeros(shape, dtype=bool)
    mask[int(np.ceil(y0)):int(np.ceil(y1)), int(np.ceil(x0)):int(np.ceil(x1))] = True
    if not mask.any():
        raise RoiError(f"ROI {tuple(array)} contains no pixel centre")
    return mask


def inside_mask(mask: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """(n,) bool: which points (n, 2) fall on a True pixel of ``mask`` (nearest pixel)."""
    xy = np.asarray(xy, dtype=np.float64)
    col = np.rint(xy[:, 0])
    row = np.rint(xy[:, 1])
    ok = np.isfinite(col) & np.isfinite(row)
    ok &= (col >= 0) & (row >= 0) & (col < mask.shape[1]) & (row < mask.shape[0])
    out = np.zeros(len(xy), dtype=bool)
    out[ok] = mask[row[ok].astype(int), col[ok].astype(int)]
    return out
