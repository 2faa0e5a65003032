"""Range images from files: NumPy arrays (.npy) and 32-bit float TIFF, depth per pixel.

Depth is the distance along the camera's axis (see :mod:`tracking._camera`) in the camera's
length unit (mm). A pixel without data is NaN, infinite or 0 (scanners write either); every such
pixel becomes NaN here. An integer image (e.g. a 16-bit PNG or TIFF depth map) is read as depth
in the same unit, 0 meaning no data.
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from ._errors import ImageError
from ._images import _read_frames, file_paths

RANGE_SUFFIXES = (".npy", ".tif", ".tiff", ".png")


def range_paths(sources: str | Path | Sequence[str | Path]) -> list[Path]:
    """The range files ``sources`` name (files, folders of ``RANGE_SUFFIXES`` files, glob patterns),
    in natural order within each source."""
    return file_paths(sources, RANGE_SUFFIXES, "range image")


def load_range_images(sources, min_valid: int = 1) -> tuple[np.ndarray, list[str]]:
    """Read range images into a float64 stack ``(n_frames, rows, cols)``, NaN where no data.

    ``sources``: files, folders or glob patterns (:func:`range_paths`), or an array
    ``(rows, cols)`` / ``(n_frames, rows, cols)``. A ``.npy`` file holds one image or a stack; a
    multi-page TIFF one image per page.

    Returns:
        The stack and a name per frame (``file`` or ``file[page]``) for messages.

    Raises:
        ImageError: a file cannot be read, the images differ in shape, or a frame has fewer than
            ``min_valid`` pixels with data (a range image with no data at all cannot place a point).
    """
    frames, names = [], []
    if isinstance(sources, np.ndarray):
        stack = sources[None] if sources.ndim == 2 else sources
        frames, names = list(stack), [f"range image {k}" for k in range(len(stack))]
    else:
        for path in range_paths(sources):
            pages = _read_range(path)
            frames.extend(pages)
            names.extend([path.name] if len(pages) == 1 else [f"{path.name}[{k}]" for k in range(len(pages))])
    shapes = {np.shape(f) for f in frames}
    if not frames or len(shapes) != 1 or len(next(iter(shapes))) != 2:
        raise ImageError(f"range images must be 2D and of one shape; got shapes {sorted(shapes)}")
    stack = np.array(frames, dtype=np.float64)
    stack[~np.isfinite(stack) | (stack == 0)] = np.nan
    for k, name in enumerate(names):
        valid = int(np.isfinite(stack[k]).sum())
        if valid < min_valid:
            raise ImageError(f"{name} (frame {k}) has no range data ({valid} valid pixels: all NaN, inf or 0); "
                             "check the file, or leave this frame out of both the images and the range images")
    return stack, names


def _read_range(path: Path) -> list[np.ndarray]:
    if path.suffix.lower() == ".npy":
        try:
            data = np.load(path, allow_pickle=False)
        except (OSError, ValueError) as error:
            raise ImageError(f"cannot read range image {path}: {error}") from error
        if data.ndim not in (2, 3) or not np.issubdtype(data.dtype, np.number):
            raise ImageError(f"range image {path} must hold a numeric (rows, cols) or (frames, rows, cols) array, "
                             f"got {data.dtype} {data.shape}")
        return list(data) if data.ndim == 3 else [data]
    return _read_frames(path)
