"""Where a batch runs: a local Dask cluster of worker processes, or an existing Dask scheduler.

A local cluster starts one worker process per GPU where JAX would see GPUs, else as many worker
processes as there are cores for ``threads`` threads each. Each worker runs one diagnosis at a time
(one Dask thread) and is started by the spawn method (JAX must not be forked once it is loaded), with
its environment set before it imports JAX (:func:`worker_env`):

- CPU workers: XLA's intra-op threads, OpenMP, MKL and OpenBLAS pinned to ``threads`` each, and
  ``JAX_PLATFORMS=cpu``, so that N workers use N x threads cores and do not oversubscribe them.
- GPU workers: ``CUDA_VISIBLE_DEVICES`` set to the worker's own device (one diagnosis per device)
  and ``XLA_PYTHON_CLIENT_PREALLOCATE=false``, so that a worker takes the device memory it needs
  rather than 75 % of it (two workers may then share a device when ``workers`` exceeds the GPUs).

On a cluster of many machines, start the workers yourself with the same environment, e.g. on each
machine ``OMP_NUM_THREADS=1 XLA_FLAGS="--xla_cpu_multi_thread_eigen=false
intra_op_parallelism_threads=1" dask worker tcp://SCHEDULER:8786 --nworkers 16 --nthreads 1``, and
give the scheduler's address to the batch; bundles and the output directory must then lie on a file
system every worker sees under the same paths.
"""

from __future__ import annotations

import importlib.util
import logging
import os
import shutil
import subprocess
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager

from refine.exceptions import BatchError

THREAD_VARIABLES = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")
_XLA_THREAD_FLAGS = ("--xla_cpu_multi_thread_eigen", "intra_op_parallelism_threads")
_CUDA_PLUGINS = ("jax_cuda12_plugin", "jax_cuda13_plugin", "jax_cuda12_pjrt", "jax_cuda13_pjrt")


def cores() -> int:
    """Cores this process may run on (its CPU affinity, else the machine's count)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def worker_env(threads: int, gpu: str | None = None, base: Mapping[str, str] | None = None) -> dict[str, str]:
    """The environment variables of one worker process, to be set before it imports JAX.

    Args:
        threads: cores the worker may use: XLA's intra-op threads and the OpenMP / MKL / OpenBLAS
            threads are set to it.
        gpu: the CUDA device the worker owns (an index or a UUID as ``nvidia-smi -L`` lists it), or
            None for a CPU worker (then ``JAX_PLATFORMS=cpu``).
        base: the environment whose ``XLA_FLAGS`` are kept (default ``os.environ``); its thread
            flags are replaced, its other flags stay.

    Returns:
        ``{name: value}`` to give to the worker (Dask's ``Nanny(env=...)``).
    """
    if threads < 1:
        raise BatchError(f"threads per worker must be at least 1, got {threads}")
    base = os.environ if base is None else base
    kept = [f for f in base.get("XLA_FLAGS", "").split() if not f.lstrip("-").startswith(
        tuple(x.lstrip("-") for x in _XLA_THREAD_FLAGS))]
    flags = kept + ["--xla_cpu_multi_thread_eigen=false", f"intra_op_parallelism_threads={threads}"]
    env = {"XLA_FLAGS": " ".join(flags), **{v: str(threads) for v in THREAD_VARIABLES}}
    if gpu is None:
        env["JAX_PLATFORMS"] = "cpu"
    else:
        env.update({"CUDA_VISIBLE_DEVICES": str(gpu), "XLA_PYTHON_CLIENT_PREALLOCATE": "false"})
    return env


def visible_gpus(env: Mapping[str, str] | None = None) -> tuple[str, ...]:
    """The CUDA devices a worker's JAX would see, found without starting JAX in this process (which
    would take the devices' memory): none where ``JAX_PLATFORMS`` excludes CUDA or no CUDA plugin
    of jaxlib is installed; else ``CUDA_VISIBLE_DEVICES`` where it is set, else ``nvidia-smi``'s
    list. Returns device indices (or UUIDs) as strings."""
    env = os.environ if env is None else env
    platforms = {p.strip() for p in env.get("JAX_PLATFORMS", "").split(",") if p.strip()}
    if platforms and not platforms & {"cuda", "gpu"}:
        return ()
    if not any(_installed(m) for m in _CUDA_PLUGINS):
        return ()
    listed = env.get("CUDA_VISIBLE_DEVICES")
    if listed is not None:
        return tuple(d.strip() for d in listed.split(",") if d.strip() and d.strip() != "-1")
    smi = shutil.which("nvidia-smi")
    if smi is None:
        return ()
    try:
        out = subprocess.run([smi, "--query-gpu=index", "--format=csv,noheader"], capture_output=True,
                             text=True, timeout=30, check=True).stdout
    except (OSError, subprocess.SubprocessError):
        return ()
    return tuple(line.strip() for line in out.splitlines() if line.strip())


def _installed(module: str) -> bool:
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):
        return False


def worker_plan(workers: int | None = None, threads: int | None = None,
                gpus: Sequence[str] | None = None) -> list[dict[str, str]]:
    """The environments of a local cluster's workers, one per worker (see :func:`worker_env`).

    Args:
        workers: number of worker processes; default one per GPU, or ``cores() // threads``.
        threads: cores per worker; default 1 on CPU, ``cores() // GPUs`` with GPUs (for the work
            that stays on the CPU).
        gpus: the devices to use; default :func:`visible_gpus`; ``()`` for CPU workers only.
            Worker ``i`` gets device ``gpus[i % len(gpus)]``.
    """
    gpus = visible_gpus() if gpus is None else tuple(gpus)
    if threads is None:
        threads = max(1, cores() // len(gpus)) if gpus else 1
    if workers is None:
        workers = len(gpus) if gpus else max(1, cores() // threads)
    if workers < 1:
        raise BatchError(f"a batch needs at least one worker, got {workers}")
    return [worker_env(threads, gpus[i % len(gpus)] if gpus else None) for i in range(workers)]


def _distributed():
    try:
        import distributed
    except ImportError as e:
        raise BatchError("batch diagnosis runs on Dask: install it with `pip install nonrigid[batch]` "
                         "(or `pip install 'dask[distributed]'`)") from e
    return distributed


@contextmanager
def local_cluster(plan: Sequence[Mapping[str, str]]) -> Iterator[object]:
    """A Dask cluster on this machine with one spawned worker process per entry of ``plan`` (the
    environments of :func:`worker_plan`), each of one Dask thread; closed on leaving."""
    distributed = _distributed()
    import dask
    from distributed.system import MEMORY_LIMIT

    threads = int(plan[0]["OMP_NUM_THREADS"])
    specs = {}
    for i, env in enumerate(plan):
        name = f"gpu{env['CUDA_VISIBLE_DEVICES']}-{i}" if "CUDA_VISIBLE_DEVICES" in env else f"cpu-{i}"
        specs[name] = {"cls": distributed.Nanny,
                       "options": {"nthreads": 1, "env": dict(env), "host": "127.0.0.1", "dashboard": False,
                                   "memory_limit": int(MEMORY_LIMIT / len(plan)), "silence_logs": logging.ERROR}}
    scheduler = {"cls": distributed.Scheduler,
                 "options": {"host": "127.0.0.1", "port": 0, "dashboard": False, "dashboard_address": None}}
    # BLAS reads its thread count when numpy loads, before a worker applies ``env``: these are set
    # in the spawning process, as Dask does with its own defaults of 1
    pre_spawn = {**dask.config.get("distributed.nanny.pre-spawn-environ", {}),
                 **{v: str(threads) for v in THREAD_VARIABLES}}
    with dask.config.set({"distributed.worker.multiprocessing-method": "spawn",
                          "distributed.nanny.pre-spawn-environ": pre_spawn}):
        cluster = distributed.SpecCluster(workers=specs, scheduler=scheduler, silence_logs=logging.ERROR,
                                          name="nonrigid-batch")
    try:
        yield cluster
    finally:
        cluster.close()


@contextmanager
def connect(scheduler=None, workers: int | None = None, threads: int | None = None,
            gpus: Sequence[str] | None = None) -> Iterator[object]:
    """A ``distributed.Client``: of the scheduler at address ``scheduler`` (or that client itself
    when one is given), or of a local cluster of :func:`worker_plan` ``(workers, threads, gpus)``."""
    distributed = _distributed()
    if isinstance(scheduler, distributed.Client):
        yield scheduler
        return
    if scheduler is not None:
        try:
            client = distributed.Client(scheduler, timeout="30s", set_as_default=False)
        except OSError as e:
            raise BatchError(f"cannot reach the Dask scheduler at {scheduler}: {e}; start one with "
                             "`dask scheduler` and workers with `dask worker ADDRESS`, or leave "
                             "--scheduler out to run on this machine") from e
        with client:
            yield client
        return
    with local_cluster(worker_plan(workers, threads, gpus)) as cluster, \
            distributed.Client(cluster, set_as_default=False) as client:
        yield client
