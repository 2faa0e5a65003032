"""The interface every linear solver implements, and the host-side factorisation cache."""

from __future__ import annotations

import importlib.util
import itertools
from abc import ABC, abstractmethod
import queue
import threading
import time
import weakref
from concurrent.futures import Future
from typing import Callable, ClassVar

import jax
import numpy as np
import scipy.sparse as sp

from ..assembly import Pattern


class LinearSolver(ABC):
    """A sparse linear solver for one :class:`~jaxfem.assembly.Pattern`, callable inside ``jax.jit``.

    Its life has three stages: the constructor analyses the pattern (once), then each matrix is
    factorised and each right-hand side solved. A solver called as ``solver(values, rhs, arrays)
    -> x`` gets the matrix entries on the pattern ``(nnz,)``, the right-hand side ``(n_dofs,)`` and
    the solver's device arrays (``rows``, ``cols``, ``diag``...) and returns ``x (n_dofs,)``. The
    matrices jaxfem hands over are symmetric (Dirichlet rows and columns replaced by the identity).
    A matrix that cannot be solved gives NaN, which Newton reads as a failed solve.

    A solver that factorises on the host subclasses :class:`HostSolver` and writes ``factor``; one
    that runs in XLA writes ``__call__``. A subclass in its own module of :mod:`jaxfem.linsolve`
    is registered by its ``name``.

    Class attributes:
        name: the name ``Solver(..., linear_solver=name)`` takes.
        rank: its place in :func:`~jaxfem.linsolve.available`'s list (lower first).
        requires: the module it needs (None: always installed).
    """

    name: ClassVar[str]
    rank: ClassVar[int] = 100
    requires: ClassVar[str | None] = None
    #: whether it takes a padded matrix (:mod:`jaxfem.padding`: an identity block of padding dofs
    #: with structural zeros); a solver that cannot is given the real sizes
    pads: ClassVar[bool] = True

    def __init__(self, pattern: Pattern):
        self.pattern = pattern

    def program_key(self) -> tuple:
        """What a compiled program that calls this solver depends on besides array shapes: solvers
        with equal keys share programs (their matrices and patterns come as arguments)."""
        return (type(self),)

    def shared(self):
        """What a shared program calls, ``(values, rhs, arrays) -> x``: nothing of one pattern may
        be kept in it (the program outlives this solver); by default the solver itself."""
        return self

    @classmethod
    def installed(cls) -> bool:
        """Whether this solver works on this machine."""
        return cls.requires is None or importlib.util.find_spec(cls.requires) is not None

    @abstractmethod
    def __call__(self, values, rhs, arrays):
        """``x (n_dofs,)`` with A(values) x = rhs, traceable inside ``jax.jit``."""


class HostSolver(LinearSolver):
    """A solver that factorises on the host (through a JAX callback) and keeps the last factorisation.

    Subclasses write :meth:`factor`; ``one_thread`` runs every call on the solver's own host
    thread (see :class:`_FactorCache`).
    """

    one_thread: ClassVar[bool] = False

    def __init__(self, pattern: Pattern):
        super().__init__(pattern)
        self._cache = _FactorCache(self.factor, one_thread=self.one_thread)
        self.host_id = next(_HOST_IDS)
        _HOSTS[self.host_id] = self

    @abstractmethod
    def factor(self, values: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
        """Factorise the matrix with entries ``values (nnz,)``; return its solve ``b -> x`` (NaN if singular)."""

    def __call__(self, values, rhs, arrays):
        out = jax.ShapeDtypeStruct(rhs.shape, rhs.dtype)
        if "host" in arrays:  # a shared program: which solver is an argument, not part of the program
            return host_call(values, rhs, arrays)
        return jax.pure_callback(self._cache, out, values, rhs, vmap_method="sequential")


    def shared(self):
        return host_call


def host_call(values, rhs, arrays):
    """A host solver's solve in a shared program: the solver is ``arrays["host"]``."""
    out = jax.ShapeDtypeStruct(rhs.shape, rhs.dtype)
    return jax.pure_callback(_host_solve, out, arrays["host"], values, rhs, vmap_method="sequential")


#: the host solvers alive, by ``host_id`` (a shared program names its solver by this argument)
_HOSTS: "weakref.WeakValueDictionary[int, HostSolver]" = weakref.WeakValueDictionary()
_HOST_IDS = itertools.count(1)


def _host_solve(host_id, values, rhs):
    """The solve of a padded system (:mod:`jaxfem.padding`) by the host solver ``host_id``: its
    real entries and unknowns come first; the padding rows are the identity."""
    solver = _HOSTS[int(host_id)]
    n, nnz = solver.pattern.n_dofs, solver.pattern.nnz
    x = np.array(rhs, dtype=np.float64)
    x[:n] = solver._cache(np.asarray(values)[:nnz], x[:n])
    return x


def csr(pattern: Pattern, vals) -> sp.csr_matrix:
    """The matrix with entries ``vals`` on ``pattern`` (scipy CSR, float64)."""
    n = pattern.n_dofs
    return sp.csr_matrix((np.asarray(vals, dtype=np.float64), pattern.cols, pattern.indptr), shape=(n, n))


def nan_solve(b):
    """The solve of a matrix that has no factorisation: NaN of ``b``'s shape."""
    return np.full(b.shape, np.nan)


class _FactorCache:
    """Keeps the last factorisation and the matrix values it belongs to: repeated solves with the
    same tangent (tangent and adjoint solves after Newton, a Jacobian's many directions) cost one
    factorisation and many cheap triangular solves. Comparing the values costs one pass over them
    (cheaper than hashing them).

    With ``one_thread`` every call runs on a host thread of the cache's own. SciPy's SuperLU
    (1.17) leaks a factorisation that is freed on another thread than the one that made it (it
    tracks its allocations per thread), and XLA runs callbacks on whichever of its threads is
    free: a diagnosis's memory then grows with every factorisation until it is killed. On one
    thread the memory stays flat (tests/test_linsolve_superlu.py); the hand-over costs some
    microseconds. A thread per cache (per solver), not one for all: two models solved side by
    side (the diagnosis fits hypotheses in parallel) factorise side by side."""

    def __init__(self, factor: Callable, one_thread: bool = False):
        self.factor = factor
        self.vals = None
        # XLA may run two callbacks of one program at once (independent solves, e.g. of a third
        # derivative): the cache and a solver's handle (PARDISO's) take one call at a time, or MKL
        # segfaults on the shared handle
        self._lock = threading.Lock()
        self._slot = [None]  # the solve of the last factorisation (a list: see the finaliser)
        self._jobs = None
        if one_thread:  # the last factorisation is freed on its own thread too, then the thread ends
            self._jobs = queue.SimpleQueue()
            _LIVE.add(self._jobs)
            threading.Thread(target=_serve, args=(self._jobs,), name="jaxfem-factor").start()
            weakref.finalize(self, _retire, self._slot, self._jobs).atexit = False

    def __call__(self, vals, rhs):
        if self._jobs is not None:
            done = Future()
            self._jobs.put((self._call, (vals, rhs), done))
            return done.result()
        with self._lock:
            return self._call(vals, rhs)

    def _call(self, vals, rhs):
        v = np.asarray(vals, dtype=np.float64)
        if not np.isfinite(v).all():
            # A state that does not solve has no factorisation; Newton reads NaN as a failed solve
            return np.full(np.shape(rhs), np.nan)
        t0 = time.perf_counter()
        factored = self.vals is None or not np.array_equal(v, self.vals)
        if factored:
            self.vals, self._slot[0] = None, None
            self._slot[0] = self.factor(v)
            self.vals = v.copy()
        t1 = time.perf_counter()
        x = self._slot[0](np.asarray(rhs, dtype=np.float64))
        _count(factored, t1 - t0, time.perf_counter() - t1)
        return x


_times_lock = threading.Lock()
_times = {"factorisations": 0, "factor_seconds": 0.0, "solves": 0, "solve_seconds": 0.0}


def _count(factored: bool, factor_s: float, solve_s: float) -> None:
    with _times_lock:
        _times["factorisations"] += factored
        _times["factor_seconds"] += factor_s if factored else 0.0
        _times["solves"] += 1
        _times["solve_seconds"] += solve_s


def host_solve_times() -> dict:
    """What the host solvers of this process did so far: ``factorisations`` and ``solves``
    (calls, a call's right-hand sides together) and their wall seconds, ``factor_seconds`` and
    ``solve_seconds`` (a solve's floor: the least its linear algebra costs)."""
    with _times_lock:
        return dict(_times)


def _serve(jobs: queue.SimpleQueue) -> None:
    """A factor cache's own thread: runs its calls in turn until told to end (None)."""
    while (job := jobs.get()) is not None:
        call, args, done = job
        if done is None:
            call(*args)
            continue
        try:
            done.set_result(call(*args))
        except BaseException as e:  # noqa: BLE001 - handed to the caller, who raises it
            done.set_exception(e)


def _retire(slot: list, jobs: queue.SimpleQueue) -> None:
    """Free the last factorisation on the thread that made it, then let that thread end.

    A finaliser runs wherever the garbage collector runs, e.g. inside another thread's start
    while a ThreadPoolExecutor's submit holds its global lock (an XLA callback starting a cache's
    thread): it must take no lock. SimpleQueue.put is reentrant and lock-free for this use (CI
    deadlocked here with a ThreadPoolExecutor: the callback waited on the new thread's start, the
    new thread's finaliser on the executors' global lock)."""
    _LIVE.discard(jobs)
    jobs.put((slot.clear, (), None))
    jobs.put(None)


#: the factor threads' queues not yet retired: told to end when the interpreter exits (before it
#: joins its threads), as concurrent.futures does for its pools
_LIVE: set = set()


def _end_all() -> None:
    for jobs in list(_LIVE):
        jobs.put(None)


threading._register_atexit(_end_all)  # noqa: SLF001 - the hook concurrent.futures uses
