"""Measurement bundles: the experiment (model sections), the observations and their roles,
reading and writing the format of ``docs/measurement-bundle.md``, and building a bundle from
tracked points. Imports neither JAX nor jaxfem."""

from refine.bundle.clouds import Clouds, read_clouds, write_clouds
from refine.bundle.experiment import Experiment, FromPointsDomain, MeshDomain, PolygonDomain, RectangleDomain
from refine.bundle.from_tracks import ModelSkeleton, bundle_from_tracks
from refine.bundle.io import Bundle, read_bundle, write_bundle, write_displacements_csv
from refine.bundle.observations import Forces, Observations
from refine.bundle.outline import outline_of_points, resolve_domain
from refine.bundle.regions import KnownRegion
from refine.bundle.roles import ROLES, assign_roles
from refine.bundle.shapes import SHAPES, EllipseShape, PolygonShape, RectangleShape

__all__ = ["SHAPES", "EllipseShape", "KnownRegion", "PolygonShape", "RectangleShape", "Clouds", "read_clouds", "write_clouds", "Bundle", "Experiment", "Forces", "FromPointsDomain", "MeshDomain", "ModelSkeleton", "Observations", "PolygonDomain",
           "ROLES", "RectangleDomain", "assign_roles", "bundle_from_tracks", "outline_of_points", "read_bundle",
           "resolve_domain", "write_bundle", "write_displacements_csv"]
