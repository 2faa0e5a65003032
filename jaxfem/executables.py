"""Compiled programs kept on disk whole, so that a later process neither traces nor lowers them.

JAX's persistent compilation cache (:mod:`jaxfem.cache`) keeps the compiled binary, but finds
it by a key computed from the lowered program: every process still traces and lowers each jitted
function once per argument shape to look it up (a small diagnosis's ~170 programs: 15-20 CPU s
before a single solve). :class:`Kept` is ``jax.jit`` of a function plus a folder of serialized
executables (``jax.experimental.serialize_executable``), found by a key the caller states:

- the function's ``name``, the function itself and what else its code depends on besides the argument shapes (``depends``:
  strings, numbers, tuples, dataclasses, functions: a function by its module, qualified name,
  byte code and closure, recursively; a function defined outside :mod:`jaxfem` also by its
  module's source text; an object whose class has ``__stable_key__(self)``, by what that returns);
- the argument structure, shapes, dtypes and weak types;
- the source text of every module of :mod:`jaxfem` (any edit of the library is another key),
  the JAX and jaxlib versions, the backend, its devices and ``XLA_FLAGS``.

A call whose key is on disk loads that executable (no trace, no lowering, no compile); any other
compiles as ``jax.jit`` does (through the persistent cache) and writes it. Where something in
``depends`` has no stable key (an object without a plain ``repr``), or the cache is off
(:func:`jaxfem.cache.cache_dir` None), the call is plain ``jax.jit``. The executables live in
the subfolder :data:`FOLDER` of the cache folder (``nonrigid cache clear`` empties it too). A
program that calls back into Python cannot be serialized. Not written either: an executable that
JAX's persistent cache gave (not compiled in this process: it serializes without its object
code), and one with a custom call (a LAPACK kernel, e.g. ``eigvalsh``: JAX registers those when
it lowers a program that uses them, and an executable loaded before that crashes the process).
"""

from __future__ import annotations

import dataclasses
import hashlib
import marshal
import os
import pickle
import sys
import threading
import time
from pathlib import Path

import jax
import numpy as np

from . import cache

#: the subfolder of the compilation cache folder the executables are kept in, and their suffix
FOLDER, SUFFIX = cache._KEPT

_UNKEYABLE = object()
_digest_lock = threading.Lock()
_digest: list = []


def library_digest() -> str:
    """A digest of the source of every module of :mod:`jaxfem` and of the JAX, jaxlib and
    backend it runs on (computed once per process)."""
    with _digest_lock:
        if not _digest:
            import jaxlib

            h = hashlib.sha256()
            root = Path(__file__).resolve().parent
            for f in sorted(root.rglob("*.py")):
                h.update(f.relative_to(root).as_posix().encode())
                h.update(f.read_bytes())
            dev = jax.devices()[0]
            h.update(repr((jax.__version__, getattr(jaxlib, "__version__", "?"), dev.platform,
                           getattr(dev, "device_kind", "?"), len(jax.devices()),
                           jax.config.jax_enable_x64, os.environ.get("XLA_FLAGS", ""))).encode())
            _digest.append(h.hexdigest())
        return _digest[0]


def _source_of(module: str) -> str:
    mod = sys.modules.get(module)
    path = getattr(mod, "__file__", None)
    if not path or not os.path.isfile(path):
        return "?"
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def stable_key(x, depth: int = 0):
    """A text that names what ``x`` makes a traced program compute, equal across processes;
    :data:`_UNKEYABLE` where there is none."""
    if depth > 12:
        return _UNKEYABLE
    if x is None or isinstance(x, (bool, int, float, str, bytes)):
        return repr(x)
    if isinstance(x, type):
        return f"type:{x.__module__}.{x.__qualname__}"
    if isinstance(x, (tuple, list)):
        parts = [stable_key(v, depth + 1) for v in x]
        return _UNKEYABLE if any(p is _UNKEYABLE for p in parts) else f"{type(x).__name__}({','.join(parts)})"
    if isinstance(x, dict):
        parts = [(stable_key(k, depth + 1), stable_key(v, depth + 1)) for k, v in x.items()]
        if any(p is _UNKEYABLE for kv in parts for p in kv):
            return _UNKEYABLE
        return "{" + ",".join(f"{k}:{v}" for k, v in sorted(parts)) + "}"
    if isinstance(x, np.ndarray):
        return f"array({x.dtype},{x.shape},{hashlib.sha256(np.ascontiguousarray(x).tobytes()).hexdigest()})"
    own = getattr(type(x), "__stable_key__", None)  # an object that states its own key
    if own is not None:
        return stable_key((type(x), own(x)), depth + 1)
    if dataclasses.is_dataclass(x):
        fields = [(f.name, getattr(x, f.name)) for f in dataclasses.fields(x)]
        return stable_key((type(x), tuple(fields)), depth + 1)
    code = getattr(x, "__code__", None)
    if code is not None:  # a function: its code, closure and (outside jaxfem) its module's source
        module = getattr(x, "__module__", None) or "?"
        cells = tuple(c.cell_contents for c in (x.__closure__ or ()))
        inner = stable_key((cells, getattr(x, "__defaults__", None)), depth + 1)
        if inner is _UNKEYABLE:
            return _UNKEYABLE
        src = "" if module.split(".")[0] == "jaxfem" else _source_of(module)
        return (f"fn:{module}.{getattr(x, '__qualname__', '?')}:"
                f"{hashlib.sha256(marshal.dumps(code)).hexdigest()}:{src}:{inner}")
    func = getattr(x, "func", None)  # functools.partial
    if func is not None and hasattr(x, "args") and hasattr(x, "keywords"):
        return stable_key(("partial", func, x.args, x.keywords), depth + 1)
    return _UNKEYABLE


def _leaf_key(v) -> tuple:
    if isinstance(v, (bool, int, float, complex)):
        return ("py", type(v).__name__)
    return (tuple(np.shape(v)), str(v.dtype), bool(getattr(v, "weak_type", False)))


class Kept:
    """``jax.jit(fn)`` whose executables are kept on disk (see the module doc).

    Args:
        fn: the function (positional arguments, pytrees of arrays and Python scalars).
        name: its name in the key (unique among the functions given the same ``depends``).
        depends: what ``fn``'s code depends on besides its arguments' shapes and its own code and
            closure (a method's object, for instance).
    """

    def __init__(self, fn, name: str, depends=()):
        self.jitted = jax.jit(fn)
        dep, code = stable_key(depends), stable_key(fn)
        self._key = None if _UNKEYABLE in (dep, code) else f"{name}|{dep}|{code}"
        self._loaded: dict = {}
        self._lock = threading.Lock()

    def _cache_size(self) -> int:
        """The programs this function holds (as ``jax.jit``'s ``_cache_size``: compiled or loaded)."""
        return self.jitted._cache_size() + len(self._loaded)

    def __call__(self, *args):
        folder = cache.cache_dir() if self._key is not None else None
        if folder is None:
            return self.jitted(*args)
        leaves, tree = jax.tree.flatten(args)
        if any(isinstance(v, jax.core.Tracer) for v in leaves):  # inside a trace: jit's own path
            return self.jitted(*args)
        sig = (tree, tuple(_leaf_key(v) for v in leaves))
        run = self._loaded.get(sig)
        if run is None:
            run = self._load_or_compile(folder / FOLDER, sig, args)
        return run(*args)

    def _load_or_compile(self, folder: Path, sig, args):
        from jax.experimental.serialize_executable import deserialize_and_load, serialize

        with self._lock:
            if sig in self._loaded:
                return self._loaded[sig]
            text = f"{library_digest()}|{self._key}|{sig[0]}|{sig[1]}"
            path = folder / (hashlib.sha256(text.encode()).hexdigest() + SUFFIX)
            run = None
            if path.is_file():
                t0 = time.perf_counter()
                try:
                    run = deserialize_and_load(*pickle.loads(path.read_bytes()))
                    cache.count_kept(time.perf_counter() - t0)
                except Exception:  # noqa: BLE001 - a damaged or foreign file: dropped, compiled again
                    path.unlink(missing_ok=True)
                    run = None
            if run is None:
                lowered = self.jitted.lower(*args)
                hits = cache.hits_here()
                run = lowered.compile()
                # not written: an executable JAX's persistent cache gave (it serializes without its
                # object code: a later load fails, "Function ... not found"), or one with a custom
                # call (a LAPACK kernel that a process registers when lowering: loaded unlowered, it crashes)
                if cache.hits_here() > hits or "custom_call" in lowered.as_text():
                    self._loaded[sig] = run
                    return run
                try:
                    data = pickle.dumps(serialize(run))
                    folder.mkdir(parents=True, exist_ok=True)
                    tmp = path.with_suffix(f".{os.getpid()}.{threading.get_ident()}.tmp")
                    tmp.write_bytes(data)
                    os.replace(tmp, path)  # whole or not at all, for processes sharing the folder
                except Exception:  # noqa: BLE001 - not serializable (a host callback) or no room: jit's own path
                    pass
            self._loaded[sig] = run
            return run
