"""Solid (3D) models of a measured object and their diagnosis: the paper's Sec. 4 cup holder, a
local model of its observed bottom that finds a hole, and the global model the finding goes into."""

from refine.solid.cup import CupShape, MeshNotClosedError, check_closed, cup_shape
from refine.solid.diagnose import SolidConfig, SolidDiagnosis, diagnose_solid, report
from refine.solid.loaded import LoadedModel

__all__ = ["CupShape", "LoadedModel", "MeshNotClosedError", "SolidConfig", "SolidDiagnosis", "check_closed",
           "cup_shape", "diagnose_solid", "report"]
