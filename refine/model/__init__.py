"""The finite-element model of a bundle, driven by its measured boundary points
(:class:`MeasuredModel`), its parametrisations (region moduli, modulus fields, shapes) and the
misfit a fit minimises (:class:`Objective`, :class:`Compiled`)."""

from refine.model.measured import MeasuredModel, domain_mesh, grid_spacing
from refine.model.objective import Compiled, Objective
from refine.model.parametrize import (Combined, ModulusField, RegionModuli, ShapeGeometry, UniformParameter,
                                      infeasibility, make_shape)

__all__ = ["Combined", "Compiled", "MeasuredModel", "ModulusField", "Objective", "RegionModuli",
           "ShapeGeometry", "UniformParameter", "domain_mesh", "grid_spacing", "infeasibility", "make_shape"]
