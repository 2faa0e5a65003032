"""Diagnose many bundles on a Dask cluster, streaming one row per bundle to the results table."""

from __future__ import annotations

import glob
import hashlib
import socket
import time
import traceback
from collections.abc import Iterable
from pathlib import Path

from refine.exceptions import BatchError
from refine.batch.table import RESULTS, Table, read_rows, row_from_report
from refine.batch.tasks import run_tasks

_GLOB = set("*?[")


def bundle_paths(items: Iterable[str | Path], list_file: str | Path | None = None) -> list[Path]:
    """The bundle directories named by ``items`` (paths or glob patterns, e.g. ``"runs/*/bundle"``)
    and by the lines of ``list_file`` (one path or pattern a line; blank lines and ``#`` comments
    skipped), resolved to absolute paths, each once, in the order given (a pattern's matches
    sorted). A pattern matching nothing raises :class:`BatchError`; a path that does not exist
    stays (its bundle fails with the reason, as a row of the table)."""
    items = list(items)
    if list_file is not None:
        f = Path(list_file)
        if not f.is_file():
            raise BatchError(f"bundle list {f} does not exist; give a text file with one bundle path a line")
        items += [s.strip() for s in f.read_text().splitlines() if s.strip() and not s.strip().startswith("#")]
    out, seen = [], set()
    for item in items:
        item = str(item)
        matches = sorted(glob.glob(item)) if _GLOB & set(item) else [item]
        if not matches:
            raise BatchError(f"no bundle matches {item!r}; check the pattern (quote it to let nonrigid expand it)")
        for m in matches:
            p = Path(m).resolve()
            if p not in seen:
                seen.add(p)
                out.append(p)
    return out


def report_names(paths: Iterable[Path]) -> dict[Path, str]:
    """The folder of each bundle's report in the output directory: the bundle's directory name, with
    a short hash of its full path added where two bundles of the batch share that name (the same
    bundle gets the same folder in every batch it is part of with the same neighbours)."""
    paths = list(paths)
    counts: dict[str, int] = {}
    for p in paths:
        counts[p.name] = counts.get(p.name, 0) + 1
    return {p: p.name if counts[p.name] == 1 else f"{p.name}-{hashlib.sha1(str(p).encode()).hexdigest()[:8]}"
            for p in paths}


def diagnose_one(bundle: str, out_dir: str, config=None, figures: bool = True) -> dict:
    """Read, diagnose and report one bundle, 2D or solid (:func:`refine.diagnose`; the task a
    worker runs); never raises: a failure is returned as the row's ``error`` and its traceback
    written to ``out_dir/error.txt`` (a run stopped after the initial model also leaves its
    report.json saying where).

    Returns the bundle's row of the results table (see :mod:`refine.batch.table`)."""
    t0 = time.perf_counter()
    out = Path(out_dir)
    row = {"bundle": bundle, "name": out.name, **_where(), "error": None}
    log: list[str] = []
    try:
        from refine.api import diagnose
        from refine.reports import read_report

        out.mkdir(parents=True, exist_ok=True)
        (out / "error.txt").unlink(missing_ok=True)
        # 2D or solid, as `nonrigid diagnose` routes and writes it (a 2D bundle's settings over its [diagnose])
        d = diagnose(bundle, config, out=out, log=log.append, figures=figures)
        row.update(row_from_report(read_report(d.written)))
    except Exception as e:  # noqa: BLE001 - a failed bundle is a row of the table; the batch goes on
        row["error"] = {"type": type(e).__name__, "message": str(e)}
        try:
            out.mkdir(parents=True, exist_ok=True)
            (out / "error.txt").write_text(traceback.format_exc())
        except OSError:
            pass
    if log:
        (out / "log.txt").write_text("\n".join(log) + "\n")
    row["seconds"] = round(time.perf_counter() - t0, 2)
    return row


def _where() -> dict:
    try:
        from distributed import get_worker

        worker = get_worker().address
    except (ImportError, ValueError):
        worker = None
    return {"worker": worker, "host": socket.gethostname()}


def diagnose_many(bundles: Iterable[str | Path], out: str | Path, config=None, scheduler=None,
                  workers: int | None = None, threads_per_worker: int | None = None, progress: bool = True,
                  figures: bool = True, retry_failed: bool = False, gpus=None) -> Table:
    """Diagnose every bundle of ``bundles`` on a Dask cluster; return the batch's :class:`Table`.

    Each bundle is read, diagnosed (:func:`refine.diagnose` with ``config``: a 2D bundle by the 2D
    diagnosis, a solid one by its 3D diagnosis) and reported in ``out/<name>/`` (report.json,
    figures, summary.txt, log.txt) on a worker; its row is appended
    to ``out/results.jsonl`` as soon as it finishes. A bundle that fails (unreadable, a solver that
    does not converge, a worker lost) gets a row with its error and the batch goes on. Bundles that
    already have a row without an error in ``out/results.jsonl`` are skipped, so running the same
    batch again resumes it after an interruption. At the end ``out/summary.txt`` (the table as text)
    and ``out/batch.png`` (causes and seconds) are written. The numbers of each report are those
    of ``diagnose`` run on its own with the same config (same seeds).

    The local workers are spawned processes, which import the calling script as a module: a script
    that calls ``diagnose_many`` must do so under ``if __name__ == "__main__":``.

    Args:
        bundles: bundle directories or glob patterns (see :func:`bundle_paths`).
        out: output directory (created).
        config: a settings object used as it is for every bundle (of the bundles' diagnosis: a
            ``DiagnoseConfig`` for 2D bundles), or a dict of settings applied over each 2D bundle's
            own ``[diagnose]`` table (a solid's: over the defaults; a setting its diagnosis has not
            is named in its log and left out); default ``{"workers": threads_per_worker}``
            (as many hypotheses fitted side by side as the worker has cores, the rest from the table).
        scheduler: address of a running Dask scheduler (``"tcp://host:8786"``), or a
            ``distributed.Client``; then ``workers``, ``threads_per_worker`` and ``gpus`` are those
            of that cluster. Default: a local cluster of spawned worker processes.
        workers: local worker processes; default one per GPU where JAX sees GPUs, else one per
            ``threads_per_worker`` cores.
        threads_per_worker: cores of each local worker (XLA, OpenMP and BLAS threads); default 1
            on CPU.
        progress: show a progress bar (tqdm, on stderr).
        figures: draw each report's figures (False: report.json and summary.txt only, faster).
        retry_failed: run again the bundles whose last row is an error (default: keep the error).
        gpus: devices of the local workers (see :func:`refine.batch.cluster.worker_plan`); ``()``
            runs on the CPU where GPUs are present.
    """
    paths = bundle_paths(bundles)
    if not paths:
        raise BatchError("no bundles to diagnose; give bundle directories, glob patterns or a list file")
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise BatchError(f"output {out} exists and is not a directory; give a directory for the reports")
    out.mkdir(parents=True, exist_ok=True)
    names = report_names(paths)
    table_path = out / RESULTS
    finished = {r["bundle"]: r for r in read_rows(table_path)}
    todo = [p for p in paths if str(p) not in finished or (retry_failed and finished[str(p)].get("error"))]
    if config is None and todo:
        config = {"workers": threads_per_worker or 1}
    if todo:
        run_tasks(diagnose_one, [(str(p), str(out / names[p]), config, figures) for p in todo], table_path,
                  _failed_row, scheduler=scheduler, workers=workers, threads=threads_per_worker, gpus=gpus,
                  progress=progress, total=len(paths), desc="diagnose", line=_error_line)
    table = Table.read(out, paths)
    (out / "summary.txt").write_text(table.summary() + "\n")
    table.plot(out / "batch.png")
    return table


def _failed_row(task: tuple, e: BaseException) -> dict:
    """The row of a bundle whose task did not return (its worker lost, say): ``task`` is
    :func:`diagnose_one`'s arguments."""
    return {"bundle": task[0], "name": Path(task[1]).name, "worker": None, "host": None,
            "error": {"type": type(e).__name__, "message": str(e)}, "seconds": None}


def _error_line(row: dict) -> str | None:
    """What to print under the progress bar about a row: its error, if any."""
    return f"{row['name']}: {row['error']['type']}: {row['error']['message']}" if row.get("error") else None
