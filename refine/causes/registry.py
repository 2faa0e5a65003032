"""The registry of causes: every way an initial model may be wrong that a diagnosis tries, as a
plug-in that says which dimensions it supports.

A cause is one module of :mod:`refine.causes` that defines a :class:`Cause` and registers it with
:func:`register` at import; :mod:`refine.causes` imports every module of the package, so a new
cause is one new file. The search (2D: :mod:`refine.diagnosis.search`; 3D: the solid engine) asks
:func:`causes` for those of its dimension and stage, in registration order, and fits the jobs each
returns; a cause never appears in the search's code by name.

Stages (what a cause starts from):

- ``"place"``: a candidate place (:class:`refine.diagnosis.localize.Candidate` in 2D, a candidate
  region of the 3D engine): a region of other stiffness, a hole, a cavity, a box;
- ``"reshape"``: a region another cause fitted (e.g. a rectangle started from a fitted ellipse);
- ``"global"``: nothing placed (another material law).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from refine.exceptions import RefineError

STAGES = ("place", "reshape", "global")


class UnknownCause(RefineError, KeyError):
    """A cause asked for by name is not registered (the message names the registered ones)."""


@dataclass(frozen=True)
class Cause:
    """A plug-in of the registry.

    Attributes:
        name: the registry key (``"ellipse"``, ``"hole"``, ``"cavity"``, ``"box"``, ``"law"``...).
        dims: the dimensions it supports (``frozenset({2})``, ``{3}`` or ``{2, 3}``).
        stage: one of :data:`STAGES`: what its jobs start from.
        names: the causes its fits may name in a report (``"stiffer-region"``,
            ``"softer-region"``, ``"hole"``, ``"cavity"``, ``"through-hole"``, ``"material-law"``).
        jobs: ``jobs(search, start) -> {job name: function of nothing -> Fitted}``: the fits to
            try from ``start`` (a candidate for ``"place"``, a :class:`~refine.diagnosis.fitted.Fitted`
            for ``"reshape"``, None for ``"global"``) in the search's context ``search`` (the
            initial model, the fitting and held-out masks, the noise, the settings, the fits so
            far). A job raises :class:`~refine.diagnosis.fitted.NotApplicable` where the data rule
            it out and any other error where it fails: the search records that as a row with its
            reason. An empty dict: nothing to try from this start.
        applies: ``applies(search) -> str | None``: why the cause cannot be tried on this
            search's body at all (None: it can), e.g. a hole in a body whose points cover it.
        doc: one line for the report and the documentation.
        order: where it comes in :func:`causes` (lower first; ties in registration order): the
            search tries a stage's causes in this order and lists their fits so.
    """

    name: str
    dims: frozenset
    stage: str
    names: tuple
    jobs: Callable
    applies: Callable = lambda search: None
    doc: str = ""
    order: int = 100

    def __post_init__(self):
        if self.stage not in STAGES:
            raise ValueError(f"cause {self.name!r}: stage must be one of {STAGES}, got {self.stage!r}")
        if not self.dims or not set(self.dims) <= {2, 3}:
            raise ValueError(f"cause {self.name!r}: dims must be a non-empty subset of {{2, 3}}, got {self.dims!r}")
        object.__setattr__(self, "dims", frozenset(self.dims))


_REGISTRY: dict[str, Cause] = {}


def register(cause: Cause) -> Cause:
    """Add ``cause`` to the registry (a module of :mod:`refine.causes` does it at import); a name
    registered twice is an error. Returns ``cause``."""
    if cause.name in _REGISTRY and _REGISTRY[cause.name] is not cause:
        raise ValueError(f"a cause named {cause.name!r} is registered already")
    _REGISTRY[cause.name] = cause
    return cause


def causes(dim: int | None = None, stage: str | None = None) -> list[Cause]:
    """The registered causes supporting ``dim`` (None: any) at ``stage`` (None: any), in
    their ``order`` (ties in registration order)."""
    from refine import causes as _package  # noqa: F401 - imports every cause module

    found = [c for c in _REGISTRY.values() if (dim is None or dim in c.dims) and (stage is None or c.stage == stage)]
    return sorted(found, key=lambda c: c.order)


def get_cause(name: str) -> Cause:
    """The registered cause ``name``."""
    from refine import causes as _package  # noqa: F401

    if name not in _REGISTRY:
        raise UnknownCause(f"no cause {name!r}; registered: {', '.join(_REGISTRY) or 'none'}")
    return _REGISTRY[name]
