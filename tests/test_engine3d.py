"""The 3D engine (refine.solid.engine): one diagnosis for any solid body, looping over the
registry's 3D causes. Fast tests on tiny blocks (tests/test_solid_inclusion.py's TINY setting):
the engine asks the registry (a toy cause registered here is tried, its failure is a row with its
reason), a sound block gives no finding, the report is schema 2; the 3D causes' files are swept;
marked slow, the real diagnosis of a tiny block with an inclusion."""

from __future__ import annotations

import json

import numpy as np
import pytest

import jaxfem as jf

from refine.causes import Cause, causes, register
from refine.causes import registry as reg


def _bundle(tmp_path, cause="stiffer-region", seed=1, **kw):
    from test_solid_inclusion import tiny_bundle

    from refine.bundle.io import read_bundle, write_bundle

    b, mesh, truth = tiny_bundle(cause, seed=seed, **kw)
    root = tmp_path / f"{cause}{seed}"
    root.mkdir()
    jf.write_vtu(root / "mesh.vtu", mesh)
    return read_bundle(write_bundle(root, b)), mesh, truth


@pytest.fixture()
def toys():
    """Toy causes of every stage registered for the test (and removed after): what they were
    asked, a place job that fits nothing new, one that raises, a global one that raises."""
    from refine.diagnosis.fitted import baseline

    asked = []

    def place(search, start):
        asked.append(("place", start))
        return {"toy copy": lambda: baseline(search.model, search.fit, search.hold, search.sigma),
                "toy broken": lambda: (_ for _ in ()).throw(RuntimeError("the toy cannot be fitted"))}

    def reshape(search, start):
        asked.append(("reshape", start))
        return {}

    def glob(search, start):
        asked.append(("global", start))
        return {"toy law": lambda: (_ for _ in ()).throw(ValueError("no such law"))}

    made = [register(Cause(f"toy-{s}", {3}, s, ("stiffer-region",), j, order=1))
            for s, j in (("place", place), ("reshape", reshape), ("global", glob))]
    yield asked
    for c in made:
        reg._REGISTRY.pop(c.name)


def test_the_3d_causes_are_one_file_each_and_registered():
    names = {c.name: c for c in causes(3)}
    assert {"ellipsoid", "cavity", "box"} <= set(names)
    for c in causes(3):
        assert 3 in c.dims and c.doc
    assert names["box"].stage == "reshape" and names["cavity"].names == ("cavity",)


def test_the_engine_tries_every_registered_cause_and_failures_are_rows(tmp_path, toys, monkeypatch):
    from refine.solid import engine
    from refine.solid.field import Blob

    bundle, mesh, truth = _bundle(tmp_path)
    blob = Blob(1, np.arange(3), np.array(truth.centre), np.array(truth.axes), np.asarray(truth.rotation), 1.0, 1.0,
                0.5)
    monkeypatch.setattr(engine, "candidates", lambda search: ([blob], None))
    real = engine.causes
    monkeypatch.setattr(engine, "causes", lambda dim, stage: [c for c in real(dim, stage) if c.name.startswith("toy")])
    d = engine.diagnose_body(bundle, engine.EngineConfig(alpha=1.0, model_error=False), log=lambda m: None)
    assert [a[0] for a in toys] == ["place", "reshape", "global"] and toys[0][1] is blob
    rep = d.report()
    assert rep["schema"] == 2 and rep["dim"] == 3 and rep["cause"] == "none" and rep["findings"] == []
    hyp = rep["decision"]["hypotheses"]
    failed = [h for h in hyp if h.get("failed")]
    assert {h["tried"] for h in failed} == {"toy broken", "toy law"}
    assert "cannot be fitted" in " ".join(h["failed"]["message"] for h in failed)
    assert rep["decision"]["candidates"][0]["source"] == "field"
    path = d.write(tmp_path / "out")
    assert json.loads(path.read_text())["schema"] == 2
    assert (tmp_path / "out" / "summary.txt").read_text().count("failed") >= 1
    assert (tmp_path / "out" / "report.html").exists()


def test_a_sound_tiny_block_gives_no_finding(tmp_path, toys):
    from refine.solid.engine import diagnose_body

    bundle, _, truth = _bundle(tmp_path, "none", seed=2)
    d = diagnose_body(bundle, log=lambda m: None)
    rep = d.report()
    assert truth is None and rep["cause"] == "none" and rep["findings"] == [] and not d.found
    assert ("global", None) in toys  # the laws are tried all the same, never chosen where the null test passes
    assert {"mooney-rivlin", "saint-venant-kirchhoff"} <= {h["law"] for h in rep["decision"]["hypotheses"]
                                                       if h["kind"] == "material-law"}
    assert rep["decision"]["model_error_std"] > 0 and d.null.p_value > 0.01


def test_a_failure_after_the_initial_model_carries_what_was_done(tmp_path, monkeypatch):
    from refine.solid import engine

    bundle, _, _ = _bundle(tmp_path)

    def boom(search):
        raise RuntimeError("the field broke")

    monkeypatch.setattr(engine, "candidates", boom)
    with pytest.raises(RuntimeError, match="the field broke") as e:
        engine.diagnose_body(bundle, engine.EngineConfig(alpha=1.0, model_error=False), log=lambda m: None)
    rep = e.value.incomplete.report()
    assert rep["incomplete"]["stage"] == "the candidates" and rep["cause"] == "none"
    assert rep["decision"]["hypotheses"][0]["cause"] == "none"


def test_gaps_among_interior_points_are_softer_candidates():
    from types import SimpleNamespace

    from refine.solid.engine import gap_candidates, interior_points

    mesh = jf.box(0, 0, 0, 10, 10, 10, 10, 10, 10, element="tet4")
    rng = np.random.default_rng(5)
    g = np.arange(0.5, 10, 1.0)
    X = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    c = rng.uniform(4.0, 6.0, 3)
    X = X[np.linalg.norm(X - c, axis=1) > 2.0]  # a ball of radius 2 with no point
    X = np.r_[X, [[0.0, 5.0, 5.0], [10.0, 3.0, 3.0]]]  # two on the surface
    model = SimpleNamespace(mesh=mesh, obs=SimpleNamespace(reference=X))
    inside = interior_points(model)
    assert inside[:-2].all() and not inside[-2:].any()
    found = gap_candidates(model)
    assert len(found) == 1 and found[0].sign == -1 and found[0].source == "gap"
    assert np.linalg.norm(found[0].centroid - c) < 0.7


@pytest.mark.slow  # a tiny block's field and the 3D causes' fits, refit, profile: minutes on a loaded core
def test_a_tiny_block_s_inclusion_is_found_through_the_registry(tmp_path):
    from refine.solid.engine import diagnose_body

    bundle, _, truth = _bundle(tmp_path)
    d = diagnose_body(bundle, log=lambda m: None)
    rep = d.report()
    assert rep["cause"] == "stiffer-region"
    f = rep["findings"][0]
    assert np.linalg.norm(np.subtract(f["centroid"], truth.centre)) < 0.1 * np.sqrt(8**2 + 4**2 + 4**2)
    assert rep["details"]["model"]["cells"] == 96 and f["details"]["coarse_fit"]["cells"] == 96
    lo, hi = f["details"]["profile"]["ratio"]
    assert lo <= truth.ratio <= hi  # the graded refit (finer than the model, not coarser) holds the truth
    kinds = {h["kind"] for h in rep["decision"]["hypotheses"]}
    assert {"ellipsoid", "box"} <= kinds


def test_nonrigid_diagnose_sends_any_body_but_an_observed_thin_wall_to_the_engine(tmp_path, capsys):
    from refine.cli.main import main

    bundle, _, _ = _bundle(tmp_path, "none", seed=2)
    out = tmp_path / "out"
    assert main(["diagnose", str(bundle.root), "--out", str(out), "--alpha", "0.01", "--max-cells", "50"]) == 0
    printed = capsys.readouterr().out
    assert "3D engine" in printed and "ignored for a solid bundle" in printed and "max_cells" in printed
    rep = json.loads((out / "report.json").read_text())
    assert rep["schema"] == 2 and rep["dim"] == 3 and rep["cause"] == "none" and rep["findings"] == []
    assert (out / "summary.txt").exists() and (out / "report.html").exists()


def test_the_box_share_holds_its_volume_and_the_cavity_holds_its_ratio(tmp_path):
    from refine.causes.box import BoxModulus, rotation
    from refine.causes.cavity import CAVITY_LOG_RATIO, Cavity
    from refine.model.measured import MeasuredModel
    from refine.solid.inclusion import cell_size

    mesh = jf.box(0, 0, 0, 12, 8, 8, 6, 4, 4, element="tet10")
    R = np.asarray(rotation(np.array([0.2, -0.3, 0.1]), np))
    assert np.allclose(R.T @ R, np.eye(3))
    half = np.array([3.0, 2.0, 1.5])
    h = cell_size(mesh)
    p = BoxModulus(mesh, np.array([6.1, 3.9, 4.2]), R, half, 0.5 * h, 0.1 * h, 0.25 * h, np.log(3.0), 0.3)
    z = np.asarray(p.z0)
    # measured 78.2 for 72.0 on these 2 mm cells: the box share overstates its volume (unlike the ellipsoid's, 1 %)
    assert (np.asarray(p.fraction(z)) * mesh.volumes()).sum() == pytest.approx(8 * half.prod(), rel=0.1)
    s = p.shape(z)
    assert s.kind == "box" and np.allclose(s.axes, sorted(half, reverse=True)) and p.infeasibility(z) is None
    bundle, tiny_mesh, truth = _bundle(tmp_path)
    model = MeasuredModel(bundle.experiment, bundle.observations, mesh=tiny_mesh)
    compiled, z0 = Cavity(model, truth.centre, truth.axes, truth.rotation, 1.0).build()
    assert z0.size == 9 and np.isfinite(compiled.predict(z0)).all()
    c = compiled.param.shape(z0)
    assert c.kind == "cavity" and c.cause == "cavity" and np.isclose(np.log(c.ratio), CAVITY_LOG_RATIO)


def test_a_mesh_split_in_eight_keeps_the_body_and_its_regions():
    from refine.solid.floor import split_mesh

    rng = np.random.default_rng(11)
    mesh = jf.box(0, 0, 0, 3, 2, 2, 3, 2, 2, element="tet4")
    inner = np.setdiff1d(np.arange(mesh.n_nodes), mesh.boundary_nodes())
    nodes = mesh.nodes.copy()
    nodes[inner] += rng.uniform(-0.2, 0.2, (inner.size, 3))  # distorted cells, not a box's pattern
    mesh = jf.to_quadratic(jf.Mesh(nodes, mesh.cells, "tet4", rng.integers(0, 3, mesh.n_cells)))
    fine = split_mesh(mesh)
    assert fine.element == "tet10" and fine.n_cells == 8 * mesh.n_cells
    assert (fine.jacobian_dets() > 0).all()
    assert np.isclose(fine.volumes().sum(), 12.0)
    for r in range(3):  # each cell's children fill it
        assert np.isclose(fine.volumes()[fine.regions == r].sum(), mesh.volumes()[mesh.regions == r].sum())
    assert len(np.unique(np.round(fine.nodes, 9), axis=0)) == fine.n_nodes  # no node twice
