"""The registry of candidate sources: every way a diagnosis proposes where to look (a gap in the
tracked points, the fitted modulus field, the measured strain map...), as a plug-in that says
which dimensions it supports.

A source is one module of :mod:`refine.causes.sources` that defines a :class:`Source` and
registers it with :func:`register_source` at import; the package imports every module in it, so a
new source is one new file. The diagnosis (2D: :func:`refine.diagnosis.candidates.data_candidates`)
asks :func:`sources` for those of its dimension, finds each one's candidates and lists them in
the sources' ``order``, one place seen twice kept once; a source never appears there by name.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Look:
    """What a source looks at.

    Attributes:
        model: the search's model (:class:`refine.model.measured.MeasuredModel`: its mesh,
            spacing, observations and experiment); field: the fitted log-modulus field per cell
            ``(n_cells,)`` (log E / E_initial); predicted: the initial model's displacements
            ``(frames, n_points, dim)``; fit: ``(n_points,)`` mask of the fitting points (no
            held-out point proposes a place); sigma: the noise (length unit); cfg: the settings
            (:class:`refine.diagnosis.config.DiagnoseConfig`).
    """

    model: object
    field: np.ndarray
    predicted: np.ndarray
    fit: np.ndarray
    sigma: float
    cfg: object

    @property
    def residuals(self) -> np.ndarray:
        """The initial model's residuals ``(frames, n_points, dim)``: measured less predicted."""
        return np.asarray(self.model.obs.displacements) - np.asarray(self.predicted)


@dataclass(frozen=True)
class Source:
    """A plug-in of the registry.

    Attributes:
        name: the registry key (``"gaps"``, ``"field"``, ``"strain"``, ``"soft-gaps"``...).
        dims: the dimensions it supports (``frozenset({2})``...).
        find: ``find(look, found) -> list[Candidate]``: its candidates (strongest first) from
            ``look`` (a :class:`Look`); ``found``: the candidates of the sources found before it
            (name -> list), empty unless ``reads``.
        order: where its candidates are listed (lower first; ties in registration order).
        reads: whether it reads the other sources' candidates: it is found after every source
            that does not (e.g. a narrower gap inside another source's softer candidate).
        doc: one line for the documentation.
    """

    name: str
    dims: frozenset
    find: Callable
    order: int = 100
    reads: bool = False
    doc: str = ""

    def __post_init__(self):
        if not self.dims or not set(self.dims) <= {2, 3}:
            raise ValueError(f"source {self.name!r}: dims must be a non-empty subset of {{2, 3}}, got {self.dims!r}")
        object.__setattr__(self, "dims", frozenset(self.dims))


_REGISTRY: dict[str, Source] = {}


def register_source(source: Source) -> Source:
    """Add ``source`` to the registry (a module of :mod:`refine.causes.sources` does it at import);
    a name registered twice is an error. Returns ``source``."""
    if source.name in _REGISTRY and _REGISTRY[source.name] is not source:
        raise ValueError(f"a candidate source named {source.name!r} is registered already")
    _REGISTRY[source.name] = source
    return source


def sources(dim: int | None = None) -> list[Source]:
    """The registered sources supporting ``dim`` (None: any), in their ``order``."""
    from refine.causes import sources as _package  # noqa: F401 - imports every source module

    return sorted((s for s in _REGISTRY.values() if dim is None or dim in s.dims), key=lambda s: s.order)


def find_all(dim: int, look: Look) -> list[list]:
    """Every ``dim`` source's candidates, in the sources' order: those that do not read the others
    found first (in order), then those that do, each given the candidates found before it."""
    found: dict[str, list] = {}
    listed = sources(dim)
    for s in [s for s in listed if not s.reads] + [s for s in listed if s.reads]:
        found[s.name] = list(s.find(look, dict(found) if s.reads else {}))
    return [found[s.name] for s in listed]
