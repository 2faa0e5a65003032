"""Measurement bundles: the experiment (model sections), the observations and their roles,
reading and writing the format of ``docs/measurement-bundle.md``, and building a bundle from
tracked points. Imports neither JAX nor jaxfem."""

from refine.bundle.experiment import Experiment, MeshDomain, PolygonDomain, RectangleDomain
from refine.bundle.from_tracks import ModelSkeleton, bundle_from_tracks
from refine.bundle.io import Bundle, read_bundle, write_bundle, write_displacements_csv
from refine.bundle.observations import Forces, Observations
from refine.bundle.regions import KnownRegion
from refine.bundle.roles import ROLES, assign_roles
from refine.bundle.shapes import SHAPES, EllipseShape, PolygonShape, RectangleShape

__all__ = ["SHAPES", "Bundle", "EllipseShape", "KnownRegion", "PolygonShape", "RectangleShape", "Experiment", "Forces", "MeshDomain", "ModelSkeleton", "Observations", "PolygonDomain",
           "ROLES", "RectangleDomain", "assign_roles", "bundle_from_tracks", "read_bundle", "write_bundle",
           "write_displacements_csv"]
