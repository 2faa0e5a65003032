"""Why a point is not measured: one small code per point and frame.

Every tracker writes ``Tracks.meta["lost_reasons"]``, an (n_frames, n) int8 array of the codes
below (0 where the point was measured), and ``meta["excluded"]``, the number of lattice nodes or
correlation points that were never made points, by reason (e.g. inside a hole). A code names the
first test the point failed; nothing the data do not support is written as a measurement.
"""

from __future__ import annotations

import numpy as np

MEASURED = 0
OFF_PATTERN = 1     # not on the pattern: hole, background, beyond the specimen's edge
SATURATED = 2       # glare: saturated pixels where the point is measured
REJECTED = 3        # the sub-pixel measurement failed (poor symmetry / correlation, no convergence)
JUMP = 4            # its motion disagrees with its neighbours' (an identity swap)
SLIP = 5            # more than half a pitch (or a subset) from the frame's global motion
LEFT_IMAGE = 6      # its pattern left the image
NOT_SEEN = 7        # its neighbourhood gave nothing to measure (no detection, no start)
NO_RANGE = 8        # no depth: the range image has a hole (NaN, inf, the scanner's no-data code) there
OFF_RANGE = 9       # its depth interpolation reaches beyond the range image's edge
RANGE_EDGE = 10     # its depth support straddles an occluding edge (a jump over the allowed step)
NO_REFERENCE = 11   # not measured in the reference frame (frame 0), so it has no reference position
SUBSET_EDGE = 12    # its subset would reach a texture-less edge (a hole's, the background's) at the pixel scale

LOST_REASONS = {
    MEASURED: "measured",
    OFF_PATTERN: "off the pattern (hole, background, edge)",
    SATURATED: "saturated (glare)",
    REJECTED: "rejected by the sub-pixel measurement",
    JUMP: "motion disagrees with its neighbours",
    SLIP: "disagrees with the frame's global motion (lattice slip)",
    LEFT_IMAGE: "left the image",
    NOT_SEEN: "nothing to measure",
    NO_RANGE: "no range data (hole in the range image)",
    OFF_RANGE: "outside the range image",
    RANGE_EDGE: "depth jumps within its range support (occluding edge)",
    NO_REFERENCE: "not measured in the reference frame",
    SUBSET_EDGE: "its subset reaches a texture-less edge (hole, background)",
}


def reason_counts(codes: np.ndarray) -> dict[str, int]:
    """{reason: count} of the non-zero ``codes`` (any shape)."""
    values, counts = np.unique(np.asarray(codes), return_counts=True)
    return {LOST_REASONS[int(v)]: int(c) for v, c in zip(values, counts) if v != MEASURED}


def first_reason(codes: np.ndarray, failed: np.ndarray, code: int) -> np.ndarray:
    """``codes`` with ``code`` written where ``failed`` and no earlier reason is set."""
    return np.where((codes == MEASURED) & failed, np.int8(code), codes).astype(np.int8)
