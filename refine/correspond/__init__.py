"""Tracking without correspondences: unlabelled clouds (outlines, surface samples, range data)
matched by a finite-element model, by the paper's Hausdorff force method (Sec. 5.1) or by a
differentiable fit of the model's outline over the grips' motion and the model's parameters; and
a sequence followed frame by frame, the model refined where its prediction fails."""

from refine.correspond.fit import Fitter, FitConfig, FrameData, held_error, split_frames
from refine.correspond.follow import FollowConfig, FollowResult, FrameRecord, follow_clouds
from refine.correspond.hausdorff import HausdorffConfig, HausdorffResult, hausdorff_track
from refine.correspond.model import CloudModel, Grips

__all__ = ["CloudModel", "FitConfig", "Fitter", "FollowConfig", "FollowResult", "FrameData", "FrameRecord", "Grips",
           "HausdorffConfig", "HausdorffResult", "follow_clouds", "hausdorff_track", "held_error", "split_frames"]
