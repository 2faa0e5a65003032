"""Tracking the articulated hand (the paper's Sec. 5): joint angles and a global pose of a coarse
:mod:`jaxfem.hand` model fitted to range clouds without correspondences and/or a few marked
points, with exact derivatives through the solve; the tracked skin strain against a truth.

    from refine.hand import HandTracker, TrackConfig, smooth, tracking_model
    tracker = HandTracker(tracking_model())                 # the default model (refined along the thumb)
    fits = tracker.track(clouds=sequence.clouds)            # (a) unlabelled range clouds
    fits = tracker.track(markers=(reference, positions))    # (b) the paper's marked points
    seq = smooth(tracker, fits, markers=(reference, positions))   # the frames together: seq.fits, seq.std
    error_chi2(seq.fits, truth, seq.covariance)             # a truth's errors in the whole sequence's covariance
"""

from .compare import angle_errors, error_chi2, skin_strain_on
from .default import tracking_model
from .smooth import MotionModel, SmoothedSequence, smooth
from .track import FrameFit, HandTracker, TrackConfig

__all__ = ["FrameFit", "HandTracker", "MotionModel", "SmoothedSequence", "TrackConfig", "angle_errors", "error_chi2",
           "skin_strain_on", "smooth", "tracking_model"]
