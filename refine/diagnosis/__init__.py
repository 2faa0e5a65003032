"""The diagnosis: show what the initial model gets wrong, decide whether it is beyond the noise,
name the cause (a stiffer or softer region, a hole, another material law), extend the model and
measure the gain on held-out points; and its report."""

from refine.diagnosis.config import DiagnoseConfig
from refine.diagnosis.pipeline import Diagnosis, diagnose

__all__ = ["DiagnoseConfig", "Diagnosis", "diagnose"]
