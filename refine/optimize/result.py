"""The one record every optimiser in refine returns, whatever its method."""

from __future__ import annotations

import sys
from dataclasses import dataclass, field
from typing import Any, TextIO

import numpy as np


@dataclass(frozen=True, eq=False)
class RefineResult:
    """Outcome of one refinement (a search, a least-squares fit, an adjoint descent).

    Attributes:
        values: the fitted parameters, name -> float (a modulus, a ratio) or array (a field).
        error: the final value of the objective the method minimised, in the objective's units.
        n_forward: number of forward (finite-element) solves, i.e. evaluations of the objective.
        n_gradient: number of gradient / adjoint / Jacobian evaluations (0 for derivative-free).
        seconds: wall-clock time of the whole run, s.
        history: one dict per step, in order (the paper's Table 3 is such a history); keys are
            method-specific, e.g. ``iteration``, the parameter name, ``error``, ``step``.
        method: short name of the method, e.g. ``"brent"``, ``"cubic+brent"``.
        converged: whether the method's own stopping test was met (not just an iteration cap).
        message: a sentence for a person: why it stopped, anything worth a second look.
    """

    values: dict[str, Any]
    error: float
    n_forward: int
    n_gradient: int = 0
    seconds: float = 0.0
    history: list[dict[str, Any]] = field(default_factory=list)
    method: str = ""
    converged: bool = False
    message: str = ""

    def format_table(self) -> str:
        """The history as a fixed-width text table, one row per step, columns in first-seen order."""
        columns: list[str] = []
        for row in self.history:
            columns.extend(k for k in row if k not in columns)
        if not columns:
            return f"{self.method}: no steps recorded"
        cells = [[_format_cell(row.get(k, "")) for k in columns] for row in self.history]
        widths = [max(len(c), *(len(r[i]) for r in cells)) for i, c in enumerate(columns)]
        lines = ["  ".join(c.rjust(w) for c, w in zip(columns, widths))]
        lines.append("  ".join("-" * w for w in widths))
        lines.extend("  ".join(c.rjust(w) for c, w in zip(r, widths)) for r in cells)
        return "\n".join(lines)

    def table(self, file: TextIO | None = None) -> None:
        """Print the history like the paper's Table 3 (iteration, parameter, error, step kind)."""
        print(self.format_table(), file=file or sys.stdout)

    def __str__(self) -> str:
        shown = ", ".join(f"{k}={_format_cell(v)}" for k, v in self.values.items())
        state = "converged" if self.converged else "NOT converged"
        return (
            f"{self.method}: {shown}; error {_format_cell(self.error)}; {state} after "
            f"{self.n_forward} forward / {self.n_gradient} gradient evaluations in "
            f"{self.seconds:.3g} s. {self.message}"
        ).strip()


def _format_cell(value: Any) -> str:
    if isinstance(value, (bool, np.bool_)):
        return str(bool(value))
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        return f"{float(value):.6g}"
    if isinstance(value, np.ndarray):
        return f"array{value.shape}" if value.size > 3 else np.array2string(value, precision=4)
    return str(value)
