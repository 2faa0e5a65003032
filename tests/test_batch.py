"""Batch diagnosis on Dask: a local 2-process cluster gives the reports of one-by-one runs, records a
broken bundle's error and goes on, and resumes; the workers' environments (CPU and GPU) as planned.

The bundles are tiny (a 40 x 30 mm sheet tracked on a 10 mm grid, one frame, a homogeneous stretch
with noise: nothing for the diagnosis to find, so it stops after the null test)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from refine.batch import BatchError, Table, bundle_paths, worker_env, worker_plan
from refine.batch.runner import report_names
from refine.bundle import Experiment, Observations, RectangleDomain, write_bundle
from refine.bundle.io import Bundle

NOISE = 0.02


def _stretch_bundle(path: Path, seed: int) -> Path:
    """A bundle whose motion the initial model explains (a homogeneous stretch) up to noise."""
    rng = np.random.default_rng(seed)
    x, y = np.meshgrid(np.arange(20.0, 61.0, 10.0), np.arange(10.0, 41.0, 10.0))
    ref = np.column_stack([x.ravel(), y.ravel()])
    ring = np.isclose(ref[:, 0], 20) | np.isclose(ref[:, 0], 60) | np.isclose(ref[:, 1], 10) | np.isclose(ref[:, 1], 40)
    roles = np.where(ring, "boundary", "guide")
    roles[np.flatnonzero(~ring)[[1, 4]]] = "validate"
    u = np.column_stack([0.08 * (ref[:, 0] - 20), -0.025 * (ref[:, 1] - 10)])
    u = (u + rng.normal(0, NOISE, u.shape))[None]
    ex = Experiment(name=path.name, kind="plane-stress", domain=RectangleDomain(20.0, 10.0, 60.0, 40.0),
                    law="neo-hookean", E=1.0, nu=0.3, thickness=1.0, noise_std=NOISE)
    obs = Observations(ids=np.arange(1, len(ref) + 1), reference=ref, roles=roles, displacements=u)
    return write_bundle(path, Bundle(ex, obs))


def _comparable(report: dict) -> dict:
    """report.json without its timing (and the provenance's seconds, compiles and time of writing)."""
    out = {k: v for k, v in report.items() if k != "seconds"}
    if "provenance" in out:
        out["provenance"] = {k: v for k, v in out["provenance"].items() if k not in ("seconds", "compiles", "written")}
    return out


# --- the workers' environments: no cluster, no GPU needed -------------------------------------------

def test_cpu_worker_pins_xla_and_blas_threads_and_keeps_other_xla_flags():
    env = worker_env(2, base={"XLA_FLAGS": "--xla_dump_to=/tmp/x intra_op_parallelism_threads=8"})
    assert env["XLA_FLAGS"].split() == ["--xla_dump_to=/tmp/x", "--xla_cpu_multi_thread_eigen=false",
                                        "intra_op_parallelism_threads=2"]
    assert env["OMP_NUM_THREADS"] == env["MKL_NUM_THREADS"] == env["OPENBLAS_NUM_THREADS"] == "2"
    assert env["JAX_PLATFORMS"] == "cpu" and "CUDA_VISIBLE_DEVICES" not in env


def test_gpu_workers_get_one_device_each_and_no_preallocation():
    plan = worker_plan(gpus=("0", "1"), threads=4)
    assert [e["CUDA_VISIBLE_DEVICES"] for e in plan] == ["0", "1"]
    assert all(e["XLA_PYTHON_CLIENT_PREALLOCATE"] == "false" and "JAX_PLATFORMS" not in e for e in plan)
    assert all("intra_op_parallelism_threads=4" in e["XLA_FLAGS"] for e in plan)
    shared = worker_plan(workers=3, gpus=("7", "9"))  # more workers than devices: round robin
    assert [e["CUDA_VISIBLE_DEVICES"] for e in shared] == ["7", "9", "7"]


def test_cpu_plan_and_bad_settings():
    assert len(worker_plan(workers=3, threads=1, gpus=())) == 3
    with pytest.raises(BatchError, match="at least one worker"):
        worker_plan(workers=0, gpus=())
    with pytest.raises(BatchError, match="at least 1"):
        worker_env(0)


def test_bundle_paths_globs_list_file_and_report_names(tmp_path):
    for d in ("a/bundle", "b/bundle", "c"):
        (tmp_path / d).mkdir(parents=True)
    listing = tmp_path / "list.txt"
    listing.write_text(f"# campaign\n{tmp_path / 'c'}\n\n{tmp_path / 'a/bundle'}\n")
    paths = bundle_paths([str(tmp_path / "*" / "bundle")], listing)
    assert paths == [tmp_path / "a/bundle", tmp_path / "b/bundle", tmp_path / "c"]  # each once, in order
    names = report_names(paths)
    assert names[tmp_path / "c"] == "c"
    assert names[tmp_path / "a/bundle"] != names[tmp_path / "b/bundle"]
    assert all(n.startswith("bundle-") for p, n in names.items() if p.name == "bundle")
    with pytest.raises(BatchError, match="no bundle matches"):
        bundle_paths([str(tmp_path / "nothing*")])


# --- a local 2-process cluster ----------------------------------------------------------------------

@pytest.fixture(scope="module")
def bundles(tmp_path_factory):
    root = tmp_path_factory.mktemp("bundles")
    a, b = _stretch_bundle(root / "sheet-a", 1), _stretch_bundle(root / "sheet-b", 2)
    broken = root / "sheet-broken"
    shutil.copytree(a, broken)
    (broken / "displacements.csv").unlink()  # on purpose
    return a, broken, b


def test_batch_matches_one_by_one_records_the_broken_bundle_and_resumes(bundles, tmp_path):
    pytest.importorskip("distributed", reason="batch diagnosis needs Dask: pip install nonrigid[batch]")
    from refine.batch import diagnose_many
    from refine.bundle import read_bundle
    from refine.diagnosis import DiagnoseConfig, diagnose
    from refine.reports import upgrade

    a, broken, b = bundles
    out = tmp_path / "out"
    config = DiagnoseConfig(workers=1)
    table = diagnose_many([a, broken, b], out, config=config, workers=2, progress=False, figures=False)
    rows = table.by_bundle()
    assert [r["name"] for r in table.rows] == ["sheet-a", "sheet-broken", "sheet-b"]
    # the broken bundle is recorded and the batch goes on
    assert rows[str(broken)]["error"]["type"] == "BundleError"
    assert "displacements.csv" in rows[str(broken)]["error"]["message"]
    assert (out / "sheet-broken" / "error.txt").is_file()
    assert len(table.failed) == 1 and Table.read(out).by_bundle() == rows
    assert all(rows[str(p)]["error"] is None and rows[str(p)]["cause"] == "none" for p in (a, b))
    assert {rows[str(p)]["worker"][:16] for p in (a, b)} == {"tcp://127.0.0.1:"}
    assert (out / "summary.txt").read_text().count("ERROR BundleError") == 1
    assert (out / "batch.png").stat().st_size > 0

    # the batch again with one bundle more (as after an interruption): only the new one runs
    new = a.parent / "sheet-never-written"
    again = diagnose_many([a, broken, b, new], out, config=config, workers=1, progress=False, figures=False)
    lines = [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]
    assert len(lines) == 4 and lines[-1]["name"] == "sheet-never-written"
    assert "not a directory" in again.by_bundle()[str(new)]["error"]["message"]
    assert {k: v for k, v in again.by_bundle().items() if k != str(new)} == rows

    # the same reports as one-by-one runs in this process (same seeds)
    for p in (a, b):
        d = diagnose(read_bundle(p), config, log=lambda m: None)
        alone = json.loads(json.dumps(upgrade(d.report()), default=lambda v: v.tolist()))  # numpy values; schema 2
        batch = json.loads((out / p.name / "report.json").read_text())
        assert read_bundle(out / p.name / "refined").experiment == read_bundle(p).experiment  # nothing found
        assert batch["findings"] == alone["findings"] == []
        np.testing.assert_allclose(_flat(_comparable(batch)), _flat(_comparable(alone)), rtol=1e-9, atol=1e-12)
        assert _keys(_comparable(batch)) == _keys(_comparable(alone))


def _flat(x) -> list[float]:
    """Every number of a JSON value, in order."""
    if isinstance(x, dict):
        return [v for k in sorted(x) for v in _flat(x[k])]
    if isinstance(x, list):
        return [v for item in x for v in _flat(item)]
    return [float(x)] if isinstance(x, (int, float)) and not isinstance(x, bool) else []


def _keys(x):
    """The structure of a JSON value with its numbers left out."""
    if isinstance(x, dict):
        return {k: _keys(v) for k, v in x.items()}
    if isinstance(x, list):
        return [_keys(v) for v in x]
    return None if isinstance(x, (int, float)) and not isinstance(x, bool) else x
