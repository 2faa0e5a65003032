"""Synthetic data with a hidden effect: a sheet solved on a finer quadratic mesh (never the
inversion's discretisation), sampled as a bundle with noise, or rendered as grid/speckle images;
skin with a stiffer scar (the paper's Secs. 3.2 and 5.1) as such a bundle."""

from refine.synthetic.sheet import CAUSES, Inclusion, Truth, grid_points, random_truth, synthetic_bundle, with_fibres
from refine.synthetic.skin import SKIN, SkinSetting, random_scar, skin_bundle

__all__ = ["CAUSES", "Inclusion", "SKIN", "SkinSetting", "Truth", "grid_points", "random_scar", "random_truth",
           "skin_bundle", "synthetic_bundle", "with_fibres"]
