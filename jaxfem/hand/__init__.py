"""A parametric hand/wrist/forearm (the paper's Sec. 5): box-like soft-tissue volumes with rigid
(or deformable) bones inside, joints with only their real degrees of freedom (a phalanx turns about
one axis, the wrist about two), meshed with locking-free ``tet10``; moved by joint angles frame by
frame; the skin's strain per frame, with and without a scar.

    from jaxfem.hand import PAPER, Box, HandModel, default_body, hand_mesh, run_motion, skin_area, standard_motions
    hand = hand_mesh(default_body(PAPER), h=24.0, snap=4.5)  # 2,412 tet10 elements, 4,193 nodes
    model = HandModel(hand)                                  # compiles once
    motion = standard_motions(hand.body)["wrist up-down"]
    result = run_motion(model, motion)
    result.max_strain, result.displacement                   # the strain-displacement curve
    wrist = skin_area(hand, Box((-16, -56, -20), (16, 0, -10)))  # an area of interest (skin facets)
    result = run_motion(model, motion, area=wrist, detector=detect)  # e.g. refine.threshold.ThresholdRule().find
    result.area_max_strain, result.threshold                 # its maximum; the detector's result

Units: mm, MPa; angles in degrees in a :class:`Motion`, radians in the kinematics.
"""

from .body import PAPER, Body, Bone, Box, HandDimensions, Joint, default_body
from .kinematics import bone_displacements, bone_transforms, rotation
from .model import HandModel, Scar, Tissues, scar_cells
from .motion import (Motion, MotionResult, reachable, run_motion, skin_area, skin_strain_function,
                     standard_motions)
from .output import plot_curves, write_motion_series
from .voxels import Hand, along, hand_mesh

__all__ = ["PAPER", "Body", "Bone", "Box", "HandDimensions", "Joint", "default_body", "bone_displacements",
           "bone_transforms", "rotation", "HandModel", "Scar", "Tissues", "scar_cells", "Motion", "MotionResult",
           "reachable", "run_motion", "skin_area", "skin_strain_function", "standard_motions", "plot_curves",
           "write_motion_series", "Hand", "along", "hand_mesh"]
