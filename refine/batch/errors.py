"""The exception a batch raises before it starts (the bundles' own failures are rows of its table)."""

from __future__ import annotations

from refine.exceptions import RefineError


class BatchError(RefineError, ValueError):
    """A batch cannot be set up as asked: no bundles, dask.distributed missing, a scheduler that
    cannot be reached, an output directory that is not a directory."""
