"""What ``diagnose`` writes for people and for ParaView: report.html (the finding and its figures,
self-contained), report.json's provenance, and PVD/VTU series read back with meshio (fields,
frame count, quadratic triangles in the refined model).

One diagnosis for the whole module (a bundle with a large stiffer region, coarse grid, one region
and no other laws tried, so that it takes about a minute on 2 cores); ``simulate``'s series are
checked in tests/test_cli.py, the writers on a tri6 model here.
"""

import base64
import json
import re

import meshio
import numpy as np
import pytest

import jaxfem as jf
from refine.bundle import write_bundle
from refine.cli import diagnose
from refine.demo_data import Inclusion, Truth, synthetic_bundle

FRAMES = 2


@pytest.fixture(scope="module")
def diagnosed(tmp_path_factory):
    from dataclasses import replace

    root = tmp_path_factory.mktemp("outputs")
    truth = Truth(inclusions=(Inclusion(jf.Ellipse(72.0, 38.0, 14.0, 10.0, 0.4), ratio=6.0),))
    bundle = synthetic_bundle(truth, seed=8, spacing=8.0, noise=0.02, fractions=(0.5, 1.0), name="big-inclusion")
    experiment = replace(bundle.experiment, extra={"diagnose": {"max_regions": 1, "seed": 4},
                                                   "meta": {"note": "test"}})
    write_bundle(root / "bundle", replace(bundle, experiment=experiment))
    d = diagnose(root / "bundle", root / "out", config={"try_laws": False, "seed": 3}, quiet=True)
    return d, root / "out"


def test_report_json_records_settings_and_provenance(diagnosed):
    d, out = diagnosed
    r = json.loads((out / "report.json").read_text())
    p = r["provenance"]
    assert set(p) >= {"version", "settings", "seed", "linear_solver", "seconds", "machine"}
    assert p["seed"] == 3 and p["settings"]["seed"] == 3  # the option over the table's 4
    assert p["settings"]["max_regions"] == 1 and p["settings"]["try_laws"] is False  # table, option
    assert p["linear_solver"]["setting"] == "auto" and p["linear_solver"]["used"] in jf.linsolve.available()
    assert set(p["machine"]) >= {"platform", "cpu_count", "jax", "backend"} and p["machine"]["cpu_count"] >= 1
    assert p["seconds"] == pytest.approx(d.seconds, abs=0.01) and p["version"]
    c = p["compiles"]  # the programs the diagnosis compiled or loaded from the cache (jaxfem.cache)
    assert c["compiled"] + c["cached"] > 0 and c["compile_seconds"] >= 0 and set(c) >= {"slowest", "cache_dir"}


def test_report_html_holds_the_finding_and_its_figures(diagnosed):
    d, out = diagnosed
    page = (out / "report.html").read_text()
    [finding] = d.findings
    assert finding["cause"] == "stiffer-region"
    assert "Finding: stiffer-region" in page
    assert f"{finding['relative_elasticity']:.2f} +- {finding['relative_elasticity_std']:.2f}" in page
    for title in ("Strain: measured, initial model, refined model", "Residuals", "Where",
                  "Hypotheses tried, and why the chosen one won", "Settings and provenance"):
        assert title in page
    images = re.findall(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"', page)
    assert len(images) == 3 and all(base64.b64decode(i).startswith(b"\x89PNG") for i in images)
    assert "<tr class=\"chosen\">" in page and "chosen: lowest BIC + held-out misfit" in page
    assert not re.search(r'(src|href)="(?!data:)', page)  # self-contained: nothing fetched from elsewhere


def _series(pvd):
    steps = jf.read_pvd(pvd)
    assert [t for t, _ in steps] == [float(k) for k in range(1, FRAMES + 1)]
    return [meshio.read(f) for _, f in steps]


def test_paraview_series_read_back(diagnosed):
    d, out = diagnosed
    obs = d.bundle.observations
    cells = {"region", "green_lagrange_strain", "principal_strain_1", "principal_strain_2", "equivalent_strain",
             "modulus", "thickness"}
    for key, fitted in (("initial", d.baseline), ("refined", d.chosen)):
        frames = _series(out / "paraview" / f"{key}.pvd")
        mesh = fitted.model.mesh
        for f, m in enumerate(frames):
            assert m.cells[0].type == mesh.el.meshio and len(m.cells[0].data) == mesh.n_cells
            assert set(m.cell_data) >= cells and m.point_data["displacement"].shape == (mesh.n_nodes, 3)
            assert m.cell_data["green_lagrange_strain"][0].shape == (mesh.n_cells, 9)
        u = np.asarray(fitted.model.solve_frames(fitted.theta))
        np.testing.assert_allclose(frames[-1].point_data["displacement"][:, :2], u[-1], atol=1e-9)
        modulus = frames[-1].cell_data["modulus"][0]
        region = frames[-1].cell_data["region"][0]
        if key == "refined":  # quadratic triangles that follow the found region, stiffer inside
            assert mesh.element == "tri6" and frames[0].cells[0].type == "triangle6"
            assert set(np.unique(region)) == {0, 1}
            ratio = modulus[region == 1].mean() / modulus[region == 0].mean()
            assert ratio == pytest.approx(d.findings[0]["relative_elasticity"], rel=1e-3)
        else:
            assert np.ptp(modulus) == 0
    points = _series(out / "paraview" / "points.pvd")
    last = points[-1]
    assert last.points.shape == (obs.n_points, 3) and last.cells[0].type == "vertex"
    np.testing.assert_allclose(last.point_data["residual_refined"][:, :2],
                               obs.displacements[-1] - d.chosen.predicted[-1], atol=1e-12)
    assert {"id", "role", "tracked", "measured_displacement", "predicted_initial", "residual_initial",
            "predicted_refined"} <= set(last.point_data)
    strain = _series(out / "paraview" / "measured_strain.pvd")
    assert strain[-1].cell_data["green_lagrange_strain"][0].shape[1] == 9


def test_the_figures_are_figure_objects_and_no_backend_is_switched(diagnosed):
    from matplotlib.figure import Figure

    from refine.diagnosis import figures

    d, out = diagnosed
    assert sorted(p.name for p in out.glob("*.png")) == ["errors.png", "regions.png", "residuals.png",
                                                        "strain_before_after.png"]
    # (strain_maps, which solves, is drawn into report.html above; these three only draw)
    assert all(isinstance(f(d), Figure) for f in (figures.residual_maps, figures.regions_map, figures.errors_table))
    import pathlib

    import refine
    for path in pathlib.Path(refine.__file__).parent.rglob("*.py"):
        assert "matplotlib.use(" not in path.read_text(), path


def test_model_series_on_quadratic_triangles(tmp_path):
    """The writers on their own: a tri6 model of a small bundle, two frames."""
    from refine.model.measured import MeasuredModel
    from refine.model.paraview import write_model_series, write_points_series
    from refine.demo_data import grid_points

    from refine.bundle import Experiment, Observations, RectangleDomain

    pts = grid_points((0.0, 0.0, 20.0, 10.0), 5.0)
    edge = (pts[:, 0] % 20 == 0) | (pts[:, 1] % 10 == 0)
    u = np.stack([s * 0.02 * pts * [1.0, -0.3] for s in (0.5, 1.0)])
    ex = Experiment(name="t", kind="plane-stress", domain=RectangleDomain(0.0, 0.0, 20.0, 10.0), law="neo-hookean",
                    E=2.0, nu=0.3, thickness=1.0)
    obs = Observations(np.arange(1, len(pts) + 1), pts, np.where(edge, "boundary", "guide"), u)
    model = MeasuredModel(ex, obs, element="tri6", h=5.0)
    theta = model.params()
    U = model.solve_frames(theta)
    write_model_series(tmp_path, "m", model, theta, U)
    write_points_series(tmp_path, "p", obs, {"m": model.at_points(U, theta)})
    frames = _series(tmp_path / "m.pvd")
    assert frames[1].cells[0].type == "triangle6" and frames[1].points.shape == (model.mesh.n_nodes, 3)
    # a uniform stretch: the strain is uniform, E_xx = ((1 + 0.02)^2 - 1) / 2 in the last frame
    assert frames[1].cell_data["green_lagrange_strain"][0][:, 0] == pytest.approx(0.5 * (1.02**2 - 1), rel=1e-6)
    assert np.allclose(frames[1].cell_data["modulus"][0], 2.0)
    p = _series(tmp_path / "p.pvd")
    assert np.abs(p[1].point_data["residual_m"]).max() < 1e-8
    np.testing.assert_array_equal(p[0].point_data["id"], obs.ids)


def test_pvd_lists_its_files_relative_to_itself(tmp_path):
    points = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 2.0]])
    files = []
    for k in range(3):
        files.append(tmp_path / "series" / f"s{k}.vtu")
        files[-1].parent.mkdir(exist_ok=True)
        jf.write_points_vtu(files[-1], points, {"u": points * k, "lost": np.array([False, True, False])})
    pvd = jf.write_pvd(tmp_path / "s.pvd", files, times=[0.5, 1.5, 2.5])
    assert 'file="series/s1.vtu"' in pvd.read_text()
    steps = jf.read_pvd(pvd)
    assert [t for t, _ in steps] == [0.5, 1.5, 2.5]
    back = meshio.read(steps[2][1])
    np.testing.assert_allclose(back.points[:, :2], points)
    np.testing.assert_allclose(back.point_data["u"], np.c_[2 * points, np.zeros(3)])
    assert back.point_data["lost"].tolist() == [0, 1, 0]
    with pytest.raises(jf.MeshError, match="one time per file"):
        jf.write_pvd(tmp_path / "t.pvd", files, times=[1.0])
