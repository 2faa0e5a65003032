"""refine.diagnose, one entry point for every body (issue 43): the diagnosis a bundle takes is read
off the bundle (never its name), settings given by name map onto that diagnosis's (the others
named), report.json is schema 2 for every body, reports written before schema 2 (fixtures in
tests/data/reports/, written by the code of main at 0a345f5: see that folder's README) upgrade
with every value they held, a run stopped after the initial model writes what it has, and a solid
bundle in a batch goes to the 3D diagnosis."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import jaxfem as jf

from refine.exceptions import SettingsError
from refine.reports import COMMON, FINDING, ReportError, read_report, upgrade

DATA = Path(__file__).parent / "data" / "reports"
OLD = ("plane_demo", "plane_stopped", "cup", "block")


def _old(name: str) -> dict:
    return json.loads((DATA / f"{name}.json").read_text())


def _kept(old: dict, new: dict) -> None:
    """Every key of ``old`` is in ``new`` with its value; a dict's keys recursively, a list's
    items one by one (a finding gains fields, it loses none)."""
    if isinstance(old, dict):
        assert isinstance(new, dict) and set(old) <= set(new), (set(old) - set(new))
        for k in old:
            _kept(old[k], new[k])
    elif isinstance(old, list):
        assert isinstance(new, list) and len(new) == len(old)
        for a, b in zip(old, new):
            _kept(a, b)
    else:
        assert new == old


@pytest.mark.parametrize("name", OLD)
def test_an_older_report_upgrades_to_schema_2_with_every_value_it_held(name):
    from refine.batch import row_from_report

    old = _old(name)
    assert "schema" not in old
    new = upgrade(old)
    assert new["schema"] == 2 and set(COMMON) <= set(new) and new["dim"] == (2 if name.startswith("plane") else 3)
    assert all(set(FINDING) <= set(f) for f in new["findings"])
    causes = {f["cause"] for f in new["findings"]}
    assert new["cause"] == (causes.pop() if len(causes) == 1 else "none" if not causes else "regions")
    if name.startswith("plane"):
        _kept(old, new)
        for f in new["findings"]:
            assert f["centroid"] == f["region"]["centroid"] and f["axes"] == f["region"]["axes"]
    elif name == "cup":  # its seconds per stage move under details, their total is the report's seconds
        _kept({k: v for k, v in old.items() if k != "seconds"}, new)
        assert new["details"]["seconds"] == old["seconds"]
        assert new["seconds"] == pytest.approx(sum(old["seconds"].values()), abs=0.01)
        assert new["decision"]["p_value"] == old["null_test"]["p_value"]
        assert [f["cause"] for f in new["findings"]] == ["hole"] * len(old["findings"])
    else:  # a block's: laid out as the 3D engine writes it, the body's own under details
        _kept({k: v for k, v in old.items() if k not in ("cause", "findings")}, new["details"])
        assert new["cause"] == old["cause"] and new["decision"]["p_value"] == old["null_test"]["p_value"]
    assert upgrade(new) == new  # schema 2 stays as it is
    json.dumps(new, allow_nan=False)
    row = row_from_report(old)  # the batch table reads any report
    assert row["cause"] == "+".join(f["cause"] for f in new["findings"]) or row["cause"] == "none"


def test_read_report_reads_a_file_or_a_folder_and_names_what_it_cannot_read(tmp_path):
    old = _old("cup")
    (tmp_path / "report.json").write_text(json.dumps(old))
    assert read_report(tmp_path) == read_report(tmp_path / "report.json") == upgrade(old)
    with pytest.raises(ReportError, match="no report at"):
        read_report(tmp_path / "missing")
    (tmp_path / "bad.json").write_text("{")
    with pytest.raises(ReportError, match="not JSON"):
        read_report(tmp_path / "bad.json")
    with pytest.raises(ReportError, match="schema 3"):
        upgrade({**upgrade(old), "schema": 3})
    with pytest.raises(ReportError, match="not a diagnosis report"):
        upgrade({"points": 3})


# ------------------------------------------------------------------- bundles with no solve at all
def _sheet_at_rest(name: str, table: dict | None = None):
    """A 2D sheet's bundle at rest (no solve): its route and its settings are read off it."""
    from refine.bundle import Bundle, Experiment, Observations, RectangleDomain

    x, y = np.meshgrid(np.linspace(0, 40, 5), np.linspace(0, 20, 3))
    pts = np.c_[x.ravel(), y.ravel()]
    roles = np.where((pts[:, 0] == 0) | (pts[:, 0] == 40), "boundary", np.where(np.arange(len(pts)) % 2, "guide",
                                                                                  "validate"))
    exp = Experiment(name=name, kind="plane-stress", domain=RectangleDomain(0.0, 0.0, 40.0, 20.0), law="neo-hookean",
                     E=1.0, nu=0.3, thickness=1.0, extra={"diagnose": table} if table else {})
    return Bundle(exp, Observations(np.arange(1, len(pts) + 1), pts, roles, np.zeros((1, len(pts), 2))))


def _box_bundle(tmp_path: Path, name: str):
    """A solid block (a tet10 box) seen on its top face, at rest: no thin wall inside a rim."""
    from refine.bundle import Bundle, Experiment, MeshDomain, Observations

    jf.write_vtu(tmp_path / "box.vtu", jf.box(0, 0, 0, 8, 4, 4, 4, 2, 2, element="tet10"))
    x, y = np.meshgrid(np.linspace(0, 8, 9), np.linspace(0, 4, 5))
    pts = np.c_[x.ravel(), y.ravel(), np.full(x.size, 4.0)]
    roles = np.where((pts[:, 0] == 0) | (pts[:, 0] == 8), "boundary", np.where(np.arange(len(pts)) % 3, "guide",
                                                                                 "validate"))
    obs = Observations(np.arange(1, len(pts) + 1), pts, roles, np.zeros((2, len(pts), 3)))
    exp = Experiment(name=name, kind="solid", domain=MeshDomain("box.vtu"), law="neo-hookean", E=1.0, nu=0.3)
    return Bundle(exp, obs, root=tmp_path)


def _cup_bundle(tmp_path: Path, name: str):
    from test_solid_diagnosis import floor_points, hand_bundle

    b = hand_bundle(tmp_path, floor_points())
    return replace(b, experiment=replace(b.experiment, name=name))


def test_the_route_is_read_off_the_bundle_never_its_name(tmp_path):
    from refine.api import route

    (tmp_path / "c").mkdir()
    bundles = {"plane": _sheet_at_rest("p"), "thin-wall": _cup_bundle(tmp_path / "c", "c"),
               "engine": _box_bundle(tmp_path, "b")}
    for name in ("cup", "block", "sheet"):  # each body under each name
        for way, b in bundles.items():
            got, reason = route(replace(b, experiment=replace(b.experiment, name=name)))
            assert got == way and (reason is None) == (way != "engine"), (name, way, reason)


def test_settings_given_by_name_map_onto_the_body_s_diagnosis_and_the_others_are_named(tmp_path):
    from refine.api import settings_for
    from refine.diagnosis.config import DiagnoseConfig
    from refine.solid.diagnose import SolidConfig
    from refine.solid.engine import EngineConfig

    rng = np.random.default_rng(43)
    alpha, n, h, seed = float(rng.uniform(1e-4, 0.05)), int(rng.integers(1, 5)), float(rng.uniform(0.5, 2)), int(
        rng.integers(0, 99))
    box = _box_bundle(tmp_path, "b")
    cfg, ignored = settings_for(box, "engine", {"alpha": alpha, "max_regions": n, "seed": seed, "max_cells": 50})
    assert cfg == EngineConfig(alpha=alpha, max_candidates=n) and ignored == ("max_cells", "seed")
    cfg, ignored = settings_for(box, "thin-wall", {"h": h, "max_regions": n, "try_rectangles": True})
    assert cfg == SolidConfig(h=h, max_candidates=n) and ignored == ("try_rectangles",)
    sheet = _sheet_at_rest("s", {"seed": seed})  # a 2D bundle's settings go over its [diagnose] table
    cfg, ignored = settings_for(sheet, "plane", {"alpha": alpha, "focus": None, "max_regions": n})
    assert (cfg.alpha, cfg.seed, cfg.max_regions, ignored) == (alpha, seed, n, ("focus",))
    for way, bundle in (("plane", sheet), ("engine", box)):
        with pytest.raises(SettingsError, match="did you mean 'alpha'"):
            settings_for(bundle, way, {"alpah": alpha})
    with pytest.raises(SettingsError, match="EngineConfig"):
        settings_for(box, "engine", DiagnoseConfig())
    with pytest.raises(SettingsError, match="DiagnoseConfig"):
        settings_for(sheet, "plane", SolidConfig())
    mine = EngineConfig(alpha=alpha)
    assert settings_for(box, "engine", mine) == (mine, ())


# --------------------------------------------------------------- a 2D diagnosis through the entry point
@pytest.fixture(scope="module")
def sheet(tmp_path_factory):
    from refine.bundle import write_bundle

    from refine.demo_data import Truth, synthetic_bundle

    b = synthetic_bundle(Truth(), seed=31, spacing=10.0, noise=0.02, fractions=(1.0,), name="plain")
    return write_bundle(tmp_path_factory.mktemp("api") / "bundle", b)


def _timeless(r: dict) -> dict:
    p = {k: v for k, v in (r.get("provenance") or {}).items() if k not in ("seconds", "compiles", "written")}
    return {**{k: v for k, v in r.items() if k != "seconds"}, "provenance": p}


def test_a_2d_bundle_is_diagnosed_and_written_by_the_entry_point(sheet, tmp_path):
    import refine

    d = refine.diagnose(sheet, {"discretisation_error": False, "try_laws": False, "max_cells": 400}, log=None)
    assert isinstance(d, refine.Diagnosis) and d.route == "plane" and d.dim == 2 and d.error is None
    path = d.write(tmp_path / "out", figures=False)
    written = read_report(path)
    assert _timeless(written) == _timeless(json.loads(json.dumps(d.report(), default=float)))
    assert _timeless(d.report()) == _timeless(upgrade(d.result.report()))  # the 2D report, keys added
    assert d.cause == written["cause"] and d.found == bool(written["findings"])
    assert (tmp_path / "out" / "summary.txt").read_text() == d.summary() + "\n"
    assert (tmp_path / "out" / "refined" / "experiment.toml").is_file()


def test_a_run_stopped_after_the_initial_model_writes_what_it_has(sheet, tmp_path, monkeypatch):
    import refine
    from refine.diagnosis import pipeline

    def interrupted(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(pipeline, "_errors", interrupted)
    with pytest.raises(KeyboardInterrupt) as e:
        refine.diagnose(sheet, {"discretisation_error": False}, out=tmp_path / "out", log=None)
    stopped = e.value.diagnosis
    assert stopped.error is e.value and stopped.written == tmp_path / "out" / "report.json"
    r = read_report(tmp_path / "out")
    assert r["dim"] == 2 and r["incomplete"]["error"] == "KeyboardInterrupt" and r["findings"] == []
    assert r["decision"]["hypotheses"][0]["cause"] == "none" and r == upgrade(json.loads(stopped.written.read_text()))
    assert "stopped" in (tmp_path / "out" / "summary.txt").read_text()


# ------------------------------------------------------------------ a solid bundle in a batch
@pytest.mark.slow  # a tiny block's data solve, the 3D engine's initial model and field, a Dask worker: minutes
def test_a_batch_sends_a_solid_bundle_to_the_3d_diagnosis(sheet, tmp_path):
    pytest.importorskip("distributed", reason="batch diagnosis needs Dask: pip install nonrigid[batch]")
    from test_solid_inclusion import tiny_bundle

    from refine.batch import diagnose_many
    from refine.bundle import write_bundle

    b, mesh, _ = tiny_bundle("none", seed=2)
    root = tmp_path / "block"
    root.mkdir()
    jf.write_vtu(root / "mesh.vtu", mesh)
    write_bundle(root, b)
    table = diagnose_many([root, sheet], tmp_path / "out", config={"alpha": 0.01, "discretisation_error": False},
                          workers=1, progress=False, figures=False)
    rows = table.by_bundle()
    assert all(r["error"] is None for r in rows.values()), rows
    for path, dim in ((root, 3), (sheet, 2)):
        r = read_report(tmp_path / "out" / path.name)
        assert r["dim"] == dim and rows[str(path)]["cause"] == r["cause"]
    assert "3D engine" in (tmp_path / "out" / "block" / "log.txt").read_text()
