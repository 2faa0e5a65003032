"""The exceptions jaxfem raises. Each message says what went wrong and what to do about it."""


class JaxfemError(Exception):
    """Base class of every error raised by jaxfem."""


class MeshError(JaxfemError, ValueError):
    """A mesh is malformed: wrong shapes, unknown element, unused or missing nodes."""


class InvertedElementError(MeshError):
    """An element has a non-positive Jacobian in the reference configuration, or a morph inverts it."""


class ProblemError(JaxfemError, ValueError):
    """A problem is ill-posed before any solve: e.g. the body is not constrained against rigid motion."""


class SolverError(JaxfemError, RuntimeError):
    """A nonlinear solve failed.

    Attributes:
        step: index of the load step that failed (0-based).
        load_factor: the load factor reached before the failure (0 = start, 1 = full load).
        reason: one of ``"no-convergence"``, ``"inverted-element"``, ``"singular-tangent"``,
            ``"nan"``.
    """

    def __init__(self, message: str, *, step: int, load_factor: float, reason: str):
        super().__init__(message)
        self.step = step
        self.load_factor = load_factor
        self.reason = reason


class OptionError(JaxfemError, ValueError):
    """An option names something jaxfem does not have: a linear solver (or one not installed here),
    a batching method, a differentiation mode."""


class UnknownParameterError(JaxfemError, KeyError):
    """A parameter pytree key that the problem does not have."""
