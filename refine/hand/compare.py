"""A tracked hand against a truth: joint-angle errors, and a skin-strain map carried from one hand
mesh onto another's skin facets (the truth's finer mesh onto the tracker's) to be subtracted.

Units: degrees for the errors; strain dimensionless.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from refine.exceptions import CorrespondenceError


def angle_errors(fits, truth) -> np.ndarray:
    """Fitted minus true joint angles, degrees, ``(n_frames, n_angles)``: ``fits`` a list of
    :class:`~refine.hand.FrameFit`, ``truth (n_frames, n_angles)`` radians in the fits' order."""
    est = np.array([f.angles for f in fits])
    truth = np.asarray(truth, float)
    if est.shape != truth.shape:
        raise CorrespondenceError(f"{est.shape} fitted angles against a truth of shape {truth.shape}: give the "
                                  "truth of the same frames and angles")
    return np.degrees(est - truth)


def skin_strain_on(hand_from, strain_from, hand_to, cos_min: float = 0.9) -> np.ndarray:
    """A skin-strain map of ``hand_from`` (one value per skin facet, ``(n_skin_from,)``) at the
    skin facets of ``hand_to`` ``(n_skin_to,)``: the value of the nearest facet centre (reference
    positions, mm) among those facing the same way (normals within ``arccos(cos_min)``), so that a
    facet on one side of a thin part never takes the other side's strain. NaN where no facet faces
    the same way."""
    strain_from = np.asarray(strain_from, float)
    if strain_from.shape != (len(hand_from.skin_facets),):
        raise CorrespondenceError(f"the strain map must have one value per skin facet "
                                  f"({len(hand_from.skin_facets)}), got shape {strain_from.shape}")
    centre = lambda h: h.mesh.nodes[h.skin_facets[:, :3]].mean(axis=1)  # noqa: E731
    c_from, c_to = centre(hand_from), centre(hand_to)
    n_from, n_to = hand_from.skin_normals(), hand_to.skin_normals()
    out = np.full(len(c_to), np.nan)
    tree = cKDTree(c_from)
    k = min(16, len(c_from))
    _, idx = tree.query(c_to, k)
    idx = idx.reshape(len(c_to), k)
    ok = np.einsum("fkd,fd->fk", n_from[idx], n_to) >= cos_min
    first = np.argmax(ok, axis=1)
    has = ok.any(axis=1)
    out[has] = strain_from[idx[has, first[has]]]
    return out
