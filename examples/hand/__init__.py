"""The paper's hand (Sec. 5). The body: a parametric hand/wrist/forearm, box-like soft-tissue
volumes with rigid (or deformable) bones inside, joints with only their real degrees of freedom (a phalanx turns about
one axis, the wrist about two), meshed with locking-free ``tet10``; moved by joint angles frame by
frame; the skin's strain per frame, with and without a scar.

    from examples.hand import PAPER, Box, HandModel, default_body, hand_mesh, run_motion, skin_area, standard_motions
    hand = hand_mesh(default_body(PAPER), h=24.0, snap=4.5)  # 2,412 tet10 elements, 4,193 nodes
    model = HandModel(hand)                                  # compiles once
    motion = standard_motions(hand.body)["wrist up-down"]
    result = run_motion(model, motion)
    result.max_strain, result.displacement                   # the strain-displacement curve
    wrist = skin_area(hand, Box((-16, -56, -20), (16, 0, -10)))  # an area of interest (skin facets)
    result = run_motion(model, motion, area=wrist, detector=detect)  # e.g. refine.threshold.ThresholdRule().find
    result.area_max_strain, result.threshold                 # its maximum; the detector's result

Units: mm, MPa; angles in degrees in a :class:`Motion`, radians in the kinematics.

Tracking it: joint angles and a global pose of a coarse
:mod:`examples.hand` model fitted to range clouds without correspondences and/or a few marked
points, with exact derivatives through the solve; the tracked skin strain against a truth.

    from examples.hand import HandTracker, TrackConfig, smooth, tracking_model
    tracker = HandTracker(tracking_model())                 # the default model (refined along the thumb)
    fits = tracker.track(clouds=sequence.clouds)            # (a) unlabelled range clouds
    fits = tracker.track(markers=(reference, positions))    # (b) the paper's marked points
    seq = smooth(tracker, fits, markers=(reference, positions))   # the frames together: seq.fits, seq.std
    error_chi2(seq.fits, truth, seq.covariance)             # a truth's errors in the whole sequence's covariance

"""

from .body import PAPER, Body, Bone, Box, HandDimensions, Joint, default_body
from .kinematics import bone_displacements, bone_transforms, rotation
from .model import HandModel, Scar, Tissues, scar_cells
from .motion import (Motion, MotionResult, reachable, run_motion, skin_area, skin_strain_function,
                     standard_motions)
from .output import plot_curves, write_motion_series
from .voxels import Hand, along, hand_mesh
from .compare import angle_errors, error_chi2, skin_strain_on
from .default import tracking_model
from .smooth import MotionModel, SmoothedSequence, smooth
from .track import FrameFit, HandTracker, TrackConfig

__all__ = ['PAPER', 'Body', 'Bone', 'Box', 'HandDimensions', 'Joint', 'default_body', 'bone_displacements', 'bone_transforms',
           'rotation', 'HandModel', 'Scar', 'Tissues', 'scar_cells', 'Motion', 'MotionResult', 'reachable',
           'run_motion', 'skin_area', 'skin_strain_function', 'standard_motions', 'plot_curves',
           'write_motion_series', 'Hand', 'along', 'hand_mesh', 'FrameFit', 'HandTracker', 'MotionModel',
           'SmoothedSequence', 'TrackConfig', 'angle_errors', 'error_chi2', 'skin_strain_on', 'smooth',
           'tracking_model']
