"""One entry point for every tracker: ``track_images(images, pattern, roi, **options)``."""

from __future__ import annotations

import dataclasses

from ._errors import OptionError
from ._grid_tracker import GridTracker
from ._speckle_tracker import SpeckleTracker
from ._tracks import Tracks

TRACKERS = {"grid": GridTracker, "speckle": SpeckleTracker}


def make_tracker(pattern: str = "grid", **options):
    """The tracker for ``pattern`` ("grid" or "speckle") configured with ``options``.

    Options are the fields of :class:`GridTracker` or :class:`SpeckleTracker`.
    """
    if pattern not in TRACKERS:
        raise OptionError(f"unknown pattern {pattern!r}; use one of {sorted(TRACKERS)}")
    kind = TRACKERS[pattern]
    names = {f.name for f in dataclasses.fields(kind)}
    unknown = sorted(set(options) - names)
    if unknown:
        raise OptionError(f"unknown option(s) {unknown} for pattern {pattern!r}; valid: {sorted(names)}")
    return kind(**options)


def track_images(images, pattern: str = "grid", roi=None, **options) -> Tracks:
    """Track points through an image sequence.

    Args:
        images: sequence of (rows, cols) arrays or image paths (TIFF/PNG), or a
            (n_frames, rows, cols) array; frame 0 is the reference.
        pattern: "grid" (painted grid: its crossings are tracked) or "speckle" (subset DIC on a
            lattice of points).
        roi: (x0, y0, x1, y1) in pixels of the first image (x = column), a boolean mask of the
            image's shape, or None for the whole image.
        **options: tracker settings, e.g. ``refiner="lines"`` for grids, ``spacing=10,
            subset=21`` for speckles (see :class:`GridTracker`, :class:`SpeckleTracker`).

    Returns:
        :class:`Tracks` in pixels.
    """
    return make_tracker(pattern, **options).track(images, roi=roi)
