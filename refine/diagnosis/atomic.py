"""Atomic writes of a diagnosis's outputs: every file (and folder) is written under a temporary
name in the folder it belongs in and then renamed over its final name (``os.replace``), so that
a run killed or failing mid-write leaves either the old file or the new one, never half of one.

:func:`replacing` (a file) and :func:`folder` (a folder such as ``paraview/`` or ``refined/``)
are context managers yielding the temporary path to write; :func:`write_text` and
:func:`save_figure` are the common cases."""

from __future__ import annotations

import os
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path


@contextmanager
def replacing(path: str | Path):
    """Yield a temporary path beside ``path`` (same folder, a hidden name); when the block ends
    without an exception it replaces ``path`` (``os.replace``: atomic on one file system), else
    it is removed and ``path`` is left as it was."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_text(path: str | Path, text: str, encoding: str = "utf-8") -> Path:
    """Write ``text`` to ``path`` atomically (:func:`replacing`); return ``path``."""
    with replacing(path) as tmp:
        with open(tmp, "w", encoding=encoding) as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
    return Path(path)


def save_figure(fig, path: str | Path, **kwargs) -> Path:
    """``fig.savefig`` into ``path`` atomically (the format from ``path``'s suffix); ``kwargs``
    go to ``savefig``."""
    path = Path(path)
    with replacing(path) as tmp:
        fig.savefig(tmp, format=path.suffix.lstrip(".") or "png", **kwargs)
    return path


@contextmanager
def folder(path: str | Path):
    """Yield a new temporary folder beside ``path``; when the block ends without an exception it
    takes ``path``'s place (an old ``path`` is moved aside first and removed after), else it is
    removed and ``path`` is left as it was."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent))
    try:
        yield tmp
        old = None
        if path.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".old", dir=path.parent))
            os.replace(path, old / path.name)
        os.replace(tmp, path)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
