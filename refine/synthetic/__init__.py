"""Synthetic data with a hidden effect: a sheet solved on a finer quadratic mesh (never the
inversion's discretisation), sampled as a bundle with noise, or rendered as grid/speckle images."""

from refine.synthetic.sheet import CAUSES, Inclusion, Truth, grid_points, random_truth, synthetic_bundle, with_fibres

__all__ = ["CAUSES", "Inclusion", "Truth", "grid_points", "random_truth", "synthetic_bundle", "with_fibres"]
