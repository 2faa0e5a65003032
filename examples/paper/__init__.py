"""The paper's Sec. 3.1 experiment (an embedded stiffer rectangle), its searches and its figures."""

from examples.paper.experiment import (BACKGROUND, BRACKET, CUBIC_TOLERANCE, INCLUSION, MIDDLE_POINTS, NAME, TOLERANCE,
                                     EmbeddedRectangle, PaperExperiment, format_rows, report, solves_to_reach)

__all__ = ["BACKGROUND", "BRACKET", "CUBIC_TOLERANCE", "EmbeddedRectangle", "INCLUSION", "MIDDLE_POINTS", "NAME",
           "PaperExperiment", "TOLERANCE", "format_rows", "report", "solves_to_reach"]
