"""Compiled programs kept on disk between processes, and a count of what each process compiled.

JAX's persistent compilation cache is on by default: a program compiled once is loaded from the
folder :func:`default_cache_dir` by later processes instead of being compiled again. Where it goes:

- ``NONRIGID_CACHE=0`` (or ``no``, ``off``, ``false``): no cache;
- ``NONRIGID_CACHE_DIR=DIR``: the folder ``DIR``;
- otherwise JAX's own ``JAX_COMPILATION_CACHE_DIR`` where set, else
  ``$XDG_CACHE_HOME/nonrigid/jax`` (``~/.cache/nonrigid/jax`` without ``XDG_CACHE_HOME``).

:func:`compilation_cache` moves or disables it from code (``nonrigid diagnose --cache DIR``);
``nonrigid cache info | clear`` shows and empties it. Every program is written, however quick its
compile (a diagnosis compiles about 170, most of them small), up to :data:`MAX_CACHE_BYTES` on disk
(least recently used entries go first; with the ``filelock`` package, which also keeps processes
sharing the folder from writing an entry at once). JAX keeps no program that calls back into
Python (the host linear solvers' programs: ``"pardiso"``, ``"superlu"``, ``"cholmod"``): those
are compiled in every process.

:func:`compile_counts` counts, for the whole process, the programs compiled and those loaded from
the cache, with their seconds (JAX's monitoring events); a caller takes a snapshot before a piece
of work and :func:`compiles_since` after it.
"""

from __future__ import annotations

import importlib.util
import os
import threading
from pathlib import Path

import jax
from jax.experimental.compilation_cache import compilation_cache as _jax_cache

CACHE_ENV = "NONRIGID_CACHE"
CACHE_DIR_ENV = "NONRIGID_CACHE_DIR"
#: the most bytes the cache folder holds (with ``filelock`` installed; without it, no limit)
MAX_CACHE_BYTES = 4 << 30
_OFF = ("0", "no", "off", "false")
_SUFFIXES = ("-cache", "-atime")  # the files JAX's cache writes (an entry and its access time)
_KEPT = ("executables", ".xla")  # jaxfem.executables' subfolder and files (whole executables)


def default_cache_dir() -> Path | None:
    """The cache folder the environment asks for (see the module doc), None where ``NONRIGID_CACHE``
    turns the cache off."""
    if os.environ.get(CACHE_ENV, "1").strip().lower() in _OFF:
        return None
    for var in (CACHE_DIR_ENV, "JAX_COMPILATION_CACHE_DIR"):
        if os.environ.get(var, "").strip():
            return Path(os.environ[var]).expanduser()
    base = os.environ.get("XDG_CACHE_HOME", "").strip() or Path.home() / ".cache"
    return Path(base) / "nonrigid" / "jax"


def compilation_cache(path, min_compile_seconds: float = 0.0) -> None:
    """Keep compiled programs in the folder ``path`` (created at the first compile), or keep none
    where ``path`` is None; takes effect at the next compile, also after programs were compiled.

    Args:
        path: the cache folder (str or Path), or None to turn the cache off for this process.
        min_compile_seconds: programs compiled faster than this are not written (0: all).
    """
    if path is None:
        jax.config.update("jax_enable_compilation_cache", False)
    else:
        jax.config.update("jax_enable_compilation_cache", True)
        jax.config.update("jax_compilation_cache_dir", str(Path(path).expanduser()))
        jax.config.update("jax_persistent_cache_min_compile_time_secs", float(min_compile_seconds))
        jax.config.update("jax_persistent_cache_min_entry_size_bytes", -1)  # small programs too
        if importlib.util.find_spec("filelock") is not None:  # JAX needs it for a size limit
            jax.config.update("jax_compilation_cache_max_size", MAX_CACHE_BYTES)
    _jax_cache.reset_cache()  # JAX opens its cache once, at the first compile: open it again


def cache_dir() -> Path | None:
    """The folder compiled programs are kept in now, None where the cache is off."""
    path = jax.config.jax_compilation_cache_dir
    return Path(path) if path and jax.config.jax_enable_compilation_cache else None


def cache_info(path=None) -> dict:
    """What the cache folder ``path`` (default: :func:`cache_dir`, else :func:`default_cache_dir`)
    holds: ``dir`` (str or None), ``enabled`` (whether this process uses it), ``entries``
    (programs kept) and ``bytes`` (their size on disk)."""
    folder = Path(path) if path is not None else (cache_dir() or default_cache_dir())
    files = _entries(folder) if folder is not None else []
    return {"dir": None if folder is None else str(folder),
            "enabled": folder is not None and cache_dir() is not None and folder.resolve() == cache_dir().resolve(),
            "entries": sum(f.name.endswith(("-cache", _KEPT[1])) for f in files), "bytes": sum(f.stat().st_size for f in files)}


def clear_cache(path=None) -> int:
    """Delete the programs kept in the folder ``path`` (default as :func:`cache_info`); only the
    files JAX's cache and :mod:`jaxfem.executables` write go, the folder and anything else in it stay. Returns the number of
    programs deleted."""
    folder = Path(path) if path is not None else (cache_dir() or default_cache_dir())
    n = 0
    for f in _entries(folder) if folder is not None else []:
        n += f.name.endswith(("-cache", _KEPT[1]))
        f.unlink(missing_ok=True)
    return n


def _entries(folder: Path) -> list[Path]:
    if not folder.is_dir():
        return []
    kept = folder / _KEPT[0]
    return ([f for f in folder.iterdir() if f.is_file() and f.name.endswith(_SUFFIXES)]
            + ([f for f in kept.iterdir() if f.is_file() and f.name.endswith(_KEPT[1])] if kept.is_dir() else []))


# ---------------------------------------------------------------------- compile counts
_lock = threading.Lock()
_hit = threading.local()  # a cache hit is announced, on the compiling thread, before its duration
_counts = {"compiled": 0, "compile_seconds": 0.0, "cached": 0, "cached_seconds": 0.0, "kept": 0, "kept_seconds": 0.0}
_by_name: dict[str, list] = {}  # program name -> [compiled, compile seconds, cached, cached seconds]
_BACKEND_COMPILE = "/jax/core/compile/backend_compile_duration"
_CACHE_HIT = "/jax/compilation_cache/cache_hits"


def _on_event(event: str, **_) -> None:
    if event == _CACHE_HIT:
        _hit.flag = True
        _hit.count = getattr(_hit, "count", 0) + 1


def hits_here() -> int:
    """Programs this thread has loaded from JAX's persistent cache so far."""
    return getattr(_hit, "count", 0)


def _on_duration(event: str, duration: float, fun_name: str = "?", **_) -> None:
    if event != _BACKEND_COMPILE:
        return
    hit, _hit.flag = getattr(_hit, "flag", False), False
    kind = "cached" if hit else "compiled"
    with _lock:
        _counts[kind] += 1
        _counts[f"{kind}_seconds" if hit else "compile_seconds"] += duration
        row = _by_name.setdefault(fun_name, [0, 0.0, 0, 0.0])
        row[2 * hit] += 1
        row[2 * hit + 1] += duration


jax.monitoring.register_event_listener(_on_event)
jax.monitoring.register_event_duration_secs_listener(_on_duration)


def count_kept(seconds: float) -> None:
    """Count one executable loaded whole (:mod:`jaxfem.executables`: no trace, no lowering)."""
    with _lock:
        _counts["kept"] += 1
        _counts["kept_seconds"] += seconds


def compile_counts() -> dict:
    """The process's programs so far: ``compiled`` (count) and ``compile_seconds`` (wall seconds
    compiling them), ``cached`` and ``cached_seconds`` (loaded from the persistent cache instead,
    after a trace and a lowering), ``kept`` and ``kept_seconds`` (executables loaded whole from
    the cache folder's ``executables/``: :mod:`jaxfem.executables`), and ``by_name`` (``{program name: [compiled, seconds, cached, seconds]}``)."""
    with _lock:
        return {**_counts, "by_name": {k: list(v) for k, v in _by_name.items()}}


def compiles_since(before: dict, top: int = 5) -> dict:
    """What :func:`compile_counts` grew by since the snapshot ``before``: ``compiled``,
    ``compile_seconds``, ``cached``, ``cached_seconds`` (seconds rounded to 0.01) and ``slowest``,
    the ``top`` programs by compile seconds (``[name, compiled, seconds]``)."""
    now = compile_counts()
    out = {k: now[k] - before[k] for k in _counts}
    out.update({k: round(out[k], 2) for k in ("compile_seconds", "cached_seconds", "kept_seconds")})
    grew = {}
    for name, row in now["by_name"].items():
        old = before["by_name"].get(name, [0, 0.0, 0, 0.0])
        if row[0] > old[0]:
            grew[name] = [row[0] - old[0], round(row[1] - old[1], 2)]
    out["slowest"] = [[k, *v] for k, v in sorted(grew.items(), key=lambda kv: -kv[1][1])[:top]]
    return out


def configure_default() -> None:
    """Turn the cache on as the environment asks (:func:`default_cache_dir`); called once when
    :mod:`jaxfem` is imported. A folder JAX was given in code before that is kept unless
    ``NONRIGID_CACHE_DIR`` names another."""
    path = default_cache_dir()
    if path is not None and jax.config.jax_compilation_cache_dir and not os.environ.get(CACHE_DIR_ENV, "").strip():
        path = jax.config.jax_compilation_cache_dir
    compilation_cache(path)
