"""Causes as plug-ins (:mod:`refine.causes.registry`): one module each, registered at import.
Importing this package imports every module in it, so that a new cause is one new file."""

import importlib
import pkgutil

from refine.causes.registry import STAGES, Cause, UnknownCause, causes, get_cause, register

for _m in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
    if _m.name != "registry" and not _m.name.startswith("_"):
        importlib.import_module(f"{__name__}.{_m.name}")

__all__ = ["STAGES", "Cause", "UnknownCause", "causes", "get_cause", "register"]
