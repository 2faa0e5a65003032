"""The grid tracker on painted grids it was not shaped by (issue 44 item 1).

Images come from tests/_grid_render.py, a renderer written apart from tracking/_synthetic.py
(Gaussian lines, Newton inverse mapping, camera blur, lighting and vignetting, JPEG), scored
against its exact truth. Pass criteria of a drawn convention (see :func:`passes`): at least 95 %
of the visible crossings (on the sheet and in view by half a pitch) tracked in the reference, and
a displacement RMS of at most 0.05 px on clean images (noise <= 1 grey level, no JPEG, line depth
>= 40 grey levels) or 0.2 px otherwise (noise 2, JPEG at quality 70, or a 20-grey-level grid).
The full sweep is benchmarks/grid_conventions.py.
"""

from __future__ import annotations

import numpy as np
import pytest

from tests._grid_render import Convention, draw, score, sequence
from tracking import GridNotFoundError, GridTracker

CLEAN_RMS_PX, HARD_RMS_PX, MIN_COVERAGE = 0.05, 0.2, 0.95


def clean(c: Convention) -> bool:
    """Images whose crossings the 0.05 px target holds for: noise <= 1, no JPEG, contrast >= 40."""
    return c.noise <= 1.0 and c.jpeg is None and c.contrast >= 40.0


def passes(c: Convention, row: dict) -> bool:
    bound = CLEAN_RMS_PX if clean(c) else HARD_RMS_PX
    return row["error"] is None and row["coverage"] >= MIN_COVERAGE and row["rms_px"] <= bound


# the report of issue 44: a clean painted grid from another renderer, dark Gaussian lines about 2 px
# wide at half depth, pitch 25 px, lighting gradient, noise 2, dark background beside the sheet,
# pulled from a clamp out of view; the same at half the size and cropped to the grid alone
REPORTED = Convention(pitch=25.0, width=2.0, sheet=175.0, contrast=120.0, background="dark", gradient=0.05,
                      noise=2.0, strain=0.15, shape=(260, 500), sheet_box=(-1e9, -1e9, 400.0, 1e9),
                      phase=(7.0, 9.0), anchor=(-0.1, 0.5), seed=44)


@pytest.mark.parametrize("case, rms", [
    (REPORTED, CLEAN_RMS_PX),
    # half the size: 1 px lines under noise 2 (the line fit sees half the pixels of half the depth)
    (REPORTED.with_(pitch=12.5, width=1.0, shape=(130, 250), sheet_box=(-1e9, -1e9, 200.0, 1e9),
                    phase=(3.5, 4.5)), 0.1),
    (REPORTED.with_(sheet_box=None, shape=(260, 320), anchor=(0.5, 0.5)), CLEAN_RMS_PX),
], ids=["pitch-25", "pitch-12.5", "cropped"])
def test_reported_thin_line_grid_is_tracked(case, rms):
    row = score(case, frames=4)
    assert row["error"] is None, row["error"]
    assert row["coverage"] >= MIN_COVERAGE, row
    assert row["rms_px"] <= rms, row


# a handful of conventions drawn over the whole promised range (the benchmark draws more); the
# draws that fail today are marked: strict, so that a fix shows (see the benchmark's rows)
DRAWN_SEED, DRAWN = 4401, 6
KNOWN_FAILURES = {
    1: "58 px pitch, a 5 x 4 crossing sheet ending in view: 94.7 % of the visible crossings",
    4: "20-grey-level 2 px lines at a 10 px pitch, blur 1.2, JPEG 70: 0.35 px RMS",
}


def _drawn(index: int) -> Convention:
    rng = np.random.default_rng(DRAWN_SEED)
    for _ in range(index + 1):
        c = draw(rng)
    return c


@pytest.mark.parametrize("index", [
    pytest.param(i, marks=pytest.mark.xfail(strict=True, reason=KNOWN_FAILURES[i])) if i in KNOWN_FAILURES else i
    for i in range(DRAWN)])
def test_drawn_convention_passes(index):
    c = _drawn(index)
    row = score(c)
    assert passes(c, row), (c, row)


def test_renderer_truth_is_on_the_painted_crossings():
    # the renderer's truth is what the images show: at every true crossing the image is darker
    # than half a pitch along both diagonals (cell centres), in the reference and the last frame
    c = Convention(pitch=16.0, width=2.0, angle=5.0, phase=(3.0, 5.0), strain=0.1, supersample=2)
    images, ref, truth = sequence(c, 2)
    for image, points in zip(images, truth):
        image = image.astype(float)

        def at(p):
            return image[int(round(p[1])), int(round(p[0]))]

        for p in points[np.all((points > 8) & (points < np.array(c.shape[::-1]) - 9), axis=1)]:
            cells = [p + 0.5 * c.pitch * np.array(d) for d in ((1, 1), (-1, 1), (1, -1), (-1, -1))]
            cells = [q for q in cells if 0 <= q[0] < c.shape[1] - 1 and 0 <= q[1] < c.shape[0] - 1]
            assert all(at(p) < at(q) - 0.5 * c.contrast for q in cells)


def test_errors_name_the_stage_and_what_to_try():
    rng = np.random.default_rng(3)
    blank = 120.0 + rng.normal(0.0, 2.0, (120, 160))
    with pytest.raises(GridNotFoundError, match="lattice stage.*pitch_range") as e:
        GridTracker().track([blank, blank])
    assert e.value.stage == "lattice"
    # a view of a few crossings: too small for a mask of four cells, or for four measured crossings
    for shape, stage in (((30, 30), "mask"), ((34, 34), "crossings")):
        images, _, _ = sequence(Convention(pitch=12.0, width=2.0, shape=shape, strain=0.02, phase=(6.0, 6.0)), 2)
        with pytest.raises(GridNotFoundError, match=f"{stage} stage.*try .*--roi") as e:
            GridTracker().track(images.astype(float))
        assert e.value.stage == stage
