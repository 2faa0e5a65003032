"""Measurement bundles: the experiment (model sections), the observations and their roles, and
reading and writing the format of ``docs/measurement-bundle.md``. Imports neither JAX nor jaxfem."""

from refine.bundle.experiment import Experiment, MeshDomain, PolygonDomain, RectangleDomain
from refine.bundle.io import Bundle, read_bundle, write_bundle, write_displacements_csv
from refine.bundle.observations import ROLES, Forces, Observations

__all__ = ["Bundle", "Experiment", "Forces", "MeshDomain", "Observations", "PolygonDomain", "ROLES",
           "RectangleDomain", "read_bundle", "write_bundle", "write_displacements_csv"]
