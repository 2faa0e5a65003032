"""The exceptions refine raises. Each message says what went wrong, where, and what to do about it."""

from __future__ import annotations

from pathlib import Path


class RefineError(Exception):
    """Base class of every error raised by refine."""


class ObservationError(RefineError, ValueError):
    """Observations given as arrays are inconsistent: shapes, duplicate ids, unknown roles, inf."""


class BundleError(RefineError, ValueError):
    """A measurement bundle on disk is malformed.

    The message starts with ``file:line:`` (or ``file:`` when no single line is at fault) so that
    an editor can jump to the problem.

    Attributes:
        path: the offending file.
        line: 1-based line number in that file, or None.
        problem: the message without the location prefix.
    """

    def __init__(self, path: str | Path, problem: str, line: int | None = None):
        where = f"{path}:{line}" if line is not None else f"{path}"
        super().__init__(f"{where}: {problem}")
        self.path = Path(path)
        self.line = line
        self.problem = problem


class SearchError(RefineError, ValueError):
    """A search was set up wrongly: a bracket that is not ordered, a non-positive tolerance."""


class ExperimentError(RefineError, ValueError):
    """An experiment description (model kind, domain, material, noise) is invalid."""


class IdentifiabilityError(RefineError, ValueError):
    """A quantity was asked for that the data cannot determine, e.g. an absolute modulus without a
    measured force (only ratios of E times thickness are identifiable then)."""


class FitError(RefineError, ValueError):
    """A fit cannot be set up or started as asked: a method given a parametrisation it does not
    handle (too many unknowns, a regulariser), or a model that does not solve at the start."""


class ParametrizationError(RefineError, ValueError):
    """A parametrisation was set up wrongly: an unknown regulariser or shape kind, kinds that do
    not match the shapes."""


class BatchError(RefineError, ValueError):
    """A batch cannot be set up as asked: no bundles, dask.distributed missing, a scheduler that
    cannot be reached, an output directory that is not a directory."""


class CorrespondenceError(RefineError, ValueError):
    """Unlabelled data cannot be matched to the model as given: an empty frame, a cloud far from the
    model's reference shape, a domain or grip the correspondence-free fit does not handle."""


class SettingsError(RefineError, ValueError):
    """Settings of a command (a ``[diagnose]`` table of experiment.toml, command-line options) are
    invalid: an unknown key (the message names the nearest known one), a wrong type or range."""


def nearest_key(key: str, known) -> str:
    """``" (did you mean 'x'?)"`` for the known key closest to ``key`` (difflib), or ``""``."""
    import difflib

    close = difflib.get_close_matches(key, list(known), n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""
