"""A tracked hand against a truth: joint-angle errors, how far they lie from zero in the reported
covariance, and a skin-strain map carried from one hand mesh onto another's skin facets (the
truth's finer mesh onto the tracker's) to be subtracted.

Units: degrees for the errors (radians in the chi-square); strain dimensionless.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree
from scipy.stats import chi2

from refine.exceptions import CorrespondenceError


def angle_errors(fits, truth) -> np.ndarray:
    """Fitted minus true joint angles, degrees, ``(n_frames, n_angles)``: ``fits`` a list of
    :class:`~examples.hand.FrameFit`, ``truth (n_frames, n_angles)`` radians in the fits' order."""
    est = np.array([f.angles for f in fits])
    truth = np.asarray(truth, float)
    if est.shape != truth.shape:
        raise CorrespondenceError(f"{est.shape} fitted angles against a truth of shape {truth.shape}: give the "
                                  "truth of the same frames and angles")
    return np.degrees(est - truth)


def error_chi2(fits, truth, covariance) -> dict:
    """The whole sequence's angle errors in their reported covariance: ``d2 = e^T C^-1 e`` over every
    angle of every frame (``e`` the errors of ``fits`` against ``truth (n_frames, n_angles)``,
    radians; ``covariance (n_frames, n_angles, n_frames, n_angles)`` radians^2, as
    :attr:`examples.hand.SmoothedSequence.covariance`). Under the stated noise (and no bias) ``d2`` is
    chi-square with ``n_frames * n_angles`` degrees of freedom: ``p`` its upper tail, small where the
    errors exceed what the reported uncertainty allows (an error the frames share included, which
    each frame's standard deviation alone cannot judge). Returns ``{"chi2", "dof", "p"}``."""
    e = np.radians(angle_errors(fits, truth)).reshape(-1)
    C = np.asarray(covariance, float)
    if C.shape != (*np.shape(truth), *np.shape(truth)):
        raise CorrespondenceError(f"a covariance of shape {C.shape} for errors of shape {np.shape(truth)}: give the "
                                  "sequence's (n_frames, n_angles, n_frames, n_angles) covariance")
    d2 = float(e @ np.linalg.solve(C.reshape(len(e), len(e)), e))
    return {"chi2": d2, "dof": len(e), "p": float(chi2.sf(d2, len(e)))}


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
