"""KLU via klujax: an XLA custom call (no callback)."""

from __future__ import annotations

from ._base import LinearSolver


class KLU(LinearSolver):
    """KLU through klujax: an XLA custom call, no Python in the loop; good for small 2D systems
    (its fill grows badly in 3D). It analyses and factorises on every call."""

    name = "klu"
    rank = 2
    requires = "klujax"

    def __call__(self, values, rhs, arrays):
        import klujax

        return klujax.solve(arrays["rows"], arrays["cols"], values, rhs)
