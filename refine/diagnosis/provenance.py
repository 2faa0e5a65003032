"""What produced a diagnosis: the package version, the settings, the seed, the linear solver, the
time it took and the machine. report.json records it under ``provenance``, so that a report read
months later says how to reproduce it."""

from __future__ import annotations

import os
import platform
from datetime import datetime, timezone
from importlib.metadata import PackageNotFoundError, version


def package_version() -> str:
    """The installed version of the ``nonrigid`` distribution (``refine``, ``jaxfem`` and
    ``tracking``), or ``"(not installed)"`` when run from a source tree that was never installed."""
    try:
        return version("nonrigid")
    except PackageNotFoundError:
        return "(not installed)"


def machine() -> dict:
    """Where it ran: ``platform``, ``python``, ``cpu_count``, ``jax`` (version), ``backend``
    (JAX's default backend, e.g. ``"cpu"``, ``"gpu"``) and ``devices`` (their kinds)."""
    import jax

    return {"platform": platform.platform(), "python": platform.python_version(), "cpu_count": os.cpu_count(),
            "jax": jax.__version__, "backend": jax.default_backend(),
            "devices": [d.device_kind for d in jax.devices()]}


def compiles(d) -> dict:
    """The XLA programs the process compiled while the diagnosis ``d`` ran (other threads' too):
    ``compiled`` and ``compile_seconds`` (wall seconds), ``cached`` and ``cached_seconds`` (loaded
    from the persistent cache instead: :mod:`jaxfem.cache`), ``slowest`` (the 5 programs by compile
    seconds, ``[name, compiled, seconds]``) and ``cache_dir`` (None: the cache was off)."""
    from jaxfem.cache import cache_dir

    where = cache_dir()
    return {**d.compiles, "cache_dir": None if where is None else str(where)}


def provenance(d) -> dict:
    """The provenance of a :class:`~refine.diagnosis.Diagnosis`: ``version``, ``settings`` (every
    field of its :class:`~refine.diagnosis.DiagnoseConfig`), ``seed``, ``linear_solver``
    (``setting`` as asked, ``used`` by the initial model: ``"auto"`` picks by size), ``seconds``
    (the diagnosis' wall time), ``compiles`` (:func:`compiles`), ``machine`` (:func:`machine`) and
    ``written`` (UTC, ISO 8601)."""
    cfg = d.config
    return {"version": package_version(), "settings": cfg.settings(), "seed": cfg.seed,
            "linear_solver": {"setting": cfg.linear_solver, "used": d.model.solver.linear_solver},
            "seconds": round(d.seconds, 2), "compiles": compiles(d), "machine": machine(),
            "written": datetime.now(timezone.utc).isoformat(timespec="seconds")}
