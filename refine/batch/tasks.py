"""Run one function over many tasks on a Dask cluster, each task's row appended to a JSONL table as
it finishes: the engine under :func:`refine.batch.diagnose_many`, and under any other batch whose
task returns a row (e.g. the diagnosis benchmark's cases, benchmarks/diagnose.py).

    rows = run_tasks(score_case, [(case,) for case in cases], "rows.jsonl", failed=lost_case_row,
                     workers=16, threads=1)

Which tasks to run (resuming a table) is the caller's choice: it knows what identifies a row.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence
from pathlib import Path

from refine.batch import cluster
from refine.batch.table import append_row


def run_tasks(fn: Callable[..., dict], tasks: Sequence[tuple], table: str | Path,
              failed: Callable[[tuple, BaseException], dict], *, scheduler=None, workers: int | None = None,
              threads: int | None = None, gpus=None, progress: bool = True, total: int | None = None,
              desc: str = "tasks", line: Callable[[dict], str | None] | None = None) -> list[dict]:
    """``fn(*task)`` for every task of ``tasks`` on a Dask cluster; each row (the dict ``fn``
    returns) is appended to the JSONL file ``table`` as soon as it arrives, in the order the tasks
    finish.

    Args:
        fn: the task; runs on a worker, so it must be importable or picklable there (a function of
            a script run as ``__main__`` is sent by value). It should record its own failures in its
            row; a task that raises anyway, or whose worker is lost, gets the row ``failed(task,
            exception)`` and the others go on.
        tasks: the positional arguments of each call.
        table: the JSONL file the rows are appended to (created; earlier rows stay).
        scheduler: where to run (see :func:`refine.batch.cluster.connect`): a scheduler's address
            or client, else a local cluster of ``workers`` spawned processes of ``threads`` cores each.
        workers: as for :func:`refine.batch.cluster.connect`.
        threads: as for :func:`refine.batch.cluster.connect`.
        gpus: as for :func:`refine.batch.cluster.connect`.
        progress: show a progress bar (tqdm, on stderr); ``total`` tasks in all (default
            ``len(tasks)``: give more when earlier rows count towards it), labelled ``desc``.
        line: a line to print under the bar about a row (None prints nothing).

    Returns:
        The rows of ``tasks`` in the order they finished.
    """
    from tqdm.auto import tqdm

    tasks = [tuple(t) for t in tasks]
    if not tasks:
        return []
    total = len(tasks) if total is None else total
    rows = []
    with cluster.connect(scheduler, workers, threads, gpus) as client:
        from distributed import as_completed

        futures = {client.submit(fn, *task, pure=False): task for task in tasks}
        bar = tqdm(total=total, initial=total - len(tasks), unit="task", desc=desc, disable=not progress)
        try:
            for future in as_completed(futures, loop=client.loop):
                try:
                    row = future.result()
                except Exception as e:  # noqa: BLE001 - a lost worker or a raising task fails that task only
                    row = failed(futures[future], e)
                append_row(Path(table), row)
                rows.append(row)
                bar.update(1)
                text = line(row) if line is not None else None
                if text:
                    bar.write(text)
                    sys.stdout.flush()  # tqdm does not: lines reach a log file as they come
                future.release()
        finally:
            bar.close()
    return rows

