"""Candidate sources as plug-ins (:mod:`refine.causes.sources.registry`): one module each,
registered at import. Importing this package imports every module in it, so that a new source
is one new file."""

import importlib
import pkgutil

from refine.causes.sources.registry import Look, Source, find_all, register_source, sources

for _m in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
    if _m.name != "registry" and not _m.name.startswith("_"):
        importlib.import_module(f"{__name__}.{_m.name}")

__all__ = ["Look", "Source", "find_all", "register_source", "sources"]
