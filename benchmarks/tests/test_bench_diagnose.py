"""The diagnosis benchmark (benchmarks/diagnose.py) on the batch runner: its cases and seeds are those
of the committed rows, its summary is re-derived from the committed rows, and cases run as runner
tasks on a local cluster (a failing case recorded, a rerun resuming); one committed case rerun end
to end through the script (slow)."""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

ROOT = Path(__file__).resolve().parents[2]
BENCH = ROOT / "benchmarks"
COMMITTED = BENCH / "results" / "diagnose.json"


@pytest.fixture(scope="module")
def bench():
    from benchmarks import diagnose

    return diagnose


@pytest.fixture(scope="module")
def committed():
    return json.loads(COMMITTED.read_text())


def _args(tmp_path: Path, **kw) -> argparse.Namespace:
    base = dict(cases=2, spacings=[10.0], noises=[0.02], causes=["none", "stiffer-region", "hole"], frames=4,
                only=None, rows=str(tmp_path / "rows.jsonl"), scheduler=None, workers=1, threads=1, no_progress=True)
    return argparse.Namespace(**{**base, **kw})


def test_cases_and_seeds_are_those_of_the_committed_rows(bench, committed, tmp_path):
    args = _args(tmp_path, cases=max(committed["cases_per_cell"]), spacings=committed["settings"]["spacings"],
                 noises=committed["settings"]["noises"], causes=committed["settings"]["causes"])
    cases = {bench.case_key(c): c for c in bench.all_cases(args)}
    rows = [r for g in committed["groups"] for r in g["rows"]]
    assert len(rows) == len(cases) == 120
    for r in rows:
        assert {k: r[k] for k in ("spacing", "noise", "cause", "k", "seed", "frames")} == cases[bench.case_key(r)]
    order = [c["k"] for c in bench.all_cases(args)]
    assert order == sorted(order)  # case index outermost: a run stopped early is balanced over the cells
    only = bench.all_cases(_args(tmp_path, only=["10/0.02/hole/1", "10/0.02/none/7"]))
    assert [bench.case_key(c) for c in only] == ["10/0.02/hole/1"]  # k 7 is not among --cases 2


def test_committed_summary_is_rederived_from_its_rows(bench, committed, tmp_path):
    rows = bench._read_rows([COMMITTED])
    bench.write_results(rows, committed["machine"], committed["settings"], tmp_path / "diagnose.json")
    again = json.loads((tmp_path / "diagnose.json").read_text())
    written = {k: v for k, v in committed.items() if k != "commit"}  # the commit that wrote the file: not a figure
    assert again == written  # every summary figure of every cell, overall, the rows themselves
    assert (tmp_path / "diagnose.png").stat().st_size > 0


def perfect_case(case: dict) -> dict:
    """A stand-in for ``run_case`` (seconds instead of minutes), run on a worker: the case's truth
    drawn under its seed and scored against a diagnosis that finds it exactly (gain 3); a case of
    index 1 raises, as a task whose worker is lost would."""
    import os

    from benchmarks._diagnose_oracle import _case_truth
    from benchmarks.diagnose import score

    if case["k"] == 1:
        raise RuntimeError("stand-in failure")
    truth = _case_truth(case)
    found = [{"cause": i.cause, "region": {"centroid": list(i.shape.params[:2]), "area": i.shape.area},
              "relative_elasticity": i.ratio, "relative_elasticity_std": 0.05 * i.ratio} for i in truth.inclusions]
    found += [{"cause": "hole", "region": {"centroid": list(h.params[:2]), "area": h.area}} for h in truth.holes]
    d = SimpleNamespace(findings=found, errors={"gain": 3.0 if found else 1.0}, seconds=0.0)
    return {**case, **score(truth, d), "load_average": list(os.getloadavg())}


def test_cases_run_on_the_batch_runner_record_a_failure_and_resume(bench, tmp_path):
    pytest.importorskip("distributed", reason="the benchmark runs on Dask: pip install nonrigid[batch]")
    args = _args(tmp_path)
    todo = bench.cases_to_run(args)
    assert len(todo) == 6 and all(c["threads"] == 1 and c["code"] for c in todo)
    bench._run(perfect_case, todo, args.rows, args, bench.error_row, lambda row: "")
    rows = bench._read_rows([args.rows])
    assert sorted(bench.case_key(r) for r in rows) == sorted(bench.case_key(c) for c in todo)
    failed = [r for r in rows if "error" in r]
    assert sorted(r["k"] for r in failed) == [1, 1, 1]
    assert all(r["error"].startswith("RuntimeError: stand-in failure") and r["seconds"] is None
               and r["missed"] and not r["passed"] for r in failed)
    assert sorted(r["truth"] for r in failed) == [[], ["hole"], ["stiffer-region"]]  # drawn again for the row
    assert all(r["passed"] and r["right_cause"] for r in rows if "error" not in r)
    assert bench.cases_to_run(args) == []  # a rerun has nothing left to run

    out = bench.write_results(rows, bench._machine(args), vars(args), tmp_path / "d.json")
    s = out["overall"]
    assert (s["cases"], s["errors"], s["pass_rate"], s["right_cause_rate"]) == (6, 3, 0.5, 0.5)
    assert s["median_centroid_error_of_diagonal"] == 0 and s["median_ratio_error"] == 0
    assert s["median_seconds"] == 0 and s["max_seconds"] == 0  # the failed tasks' seconds are unknown
    assert [g["cause"] for g in out["groups"]] == ["none", "stiffer-region", "hole"]
    assert all((g["cases"], g["errors"]) == (2, 1) for g in out["groups"])


@pytest.mark.slow  # one diagnosis in a fresh worker: ~1 minute on a quiet 2-core machine, more under load
def test_a_committed_case_rerun_through_the_script_gives_its_row(committed, tmp_path):
    pytest.importorskip("distributed", reason="the benchmark runs on Dask: pip install nonrigid[batch]")
    key = "10/0.05/none/1"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))}
    subprocess.run([sys.executable, "-m", "benchmarks.diagnose", "--cases", "2", "--spacings", "10", "--noises", "0.05",
                    "--causes", "none", "--only", key, "--workers", "1", "--threads", "2", "--no-progress",
                    "--rows", str(tmp_path / "rows.jsonl"), "--out", str(tmp_path / "d.json")], env=env, check=True)
    row = json.loads((tmp_path / "rows.jsonl").read_text())
    old = next(r for g in committed["groups"] for r in g["rows"] if g["spacing"] == 10 and g["noise"] == 0.05
               and g["cause"] == "none" and r["k"] == 1)
    assert (row["found"], row["truth"], row["passed"], row["gain"], row["points"]) == (
        old["found"], old["truth"], old["passed"], old["gain"], old["points"])
    # the hypotheses' misfits are the search's, on the search's frames since the search chose a subset
    # of frames (issue 22 item 2): the committed rows (df5f359) predate it and carry the misfits on every
    # frame. Compared: the hypotheses' names and counts, and the chosen model's misfits on every frame
    # (its final refit) to their printed digits
    for a, b in zip(row["hypotheses"], old["hypotheses"], strict=True):
        assert a["hypothesis"].split(" chi2")[0] == b["hypothesis"].split(" chi2")[0] and a["k"] == b["k"]
    new_fit, old_fit = (re.search(r"chi2 (\S+) holdout (\S+)", r["chosen"]).groups() for r in (row, old))
    assert row["chosen"].split(" chi2")[0] == old["chosen"].split(" chi2")[0]
    assert [float(x) for x in new_fit] == pytest.approx([float(x) for x in old_fit], abs=1.0)
