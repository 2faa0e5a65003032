"""Batch diagnosis: many bundles diagnosed on a Dask cluster (this machine's cores or GPUs, or a
cluster of many machines), each bundle's report in its own folder and one row per bundle streamed
to a JSONL table; resumable, a failed bundle recorded and the batch going on.

    from refine.batch import diagnose_many
    table = diagnose_many(["runs/*/bundle"], "reports")        # a local cluster, one worker per core
    print(table.summary())

Under it, :func:`run_tasks` runs any function returning a row over many tasks the same way (the
diagnosis benchmark's cases run on it).

Needs the optional extra ``pip install nonrigid[batch]`` (Dask distributed). From the command
line: ``nonrigid batch diagnose BUNDLES... --out DIR [--scheduler ADDRESS]``.
"""

from refine.batch.cluster import visible_gpus, worker_env, worker_plan
from refine.exceptions import BatchError
from refine.batch.runner import bundle_paths, diagnose_many, diagnose_one
from refine.batch.table import RESULTS, Table, row_from_report
from refine.batch.tasks import run_tasks

__all__ = ["BatchError", "RESULTS", "Table", "bundle_paths", "diagnose_many", "diagnose_one", "row_from_report",
           "run_tasks", "visible_gpus", "worker_env", "worker_plan"]
