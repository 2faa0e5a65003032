"""Nothing lost in a diagnosis: shapes stay feasible (positive semi-axes, bounded log moduli, no
overflow), a hypothesis that fails is a row of the hypotheses table with its reason while the
search goes on, a failure (or an interrupt) after the initial model still writes report.json,
summary.txt and report.html and ends ``nonrigid diagnose`` non-zero, and every output is written
atomically."""

import json
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from types import SimpleNamespace

import numpy as np
import pytest

import jaxfem as jf
from refine.diagnosis import atomic
from refine.diagnosis.config import DiagnoseConfig
from refine.diagnosis.shapes import RegionShape
from refine.exceptions import RefineError


# ------------------------------------------------------------------------- feasible shapes
def _ellipse_geometry(rng, quality: bool = False):
    """A rotating ellipse's geometry on a plate; ``quality``: also refuse squashed cells."""
    from refine.model.parametrize import ShapeGeometry

    start = jf.Ellipse(50.0, 30.0, *rng.uniform(6, 9, 2), rng.uniform(0, np.pi))
    mesh = jf.plate(0, 0, 100, 60, 3.0, inclusions=[start])
    return ShapeGeometry(jf.morph(mesh, [start]), np.asarray([start.params]), scale=2.0, rotate=True,
                         mesh=mesh if quality else None, min_axis=1.0)


def test_a_fit_driven_towards_a_negative_axis_stays_feasible():
    """The residual pulls one semi-axis to a negative value: every step the optimiser evaluates
    keeps both semi-axes above ``min_axis`` (the steps past it are refused unsolved)."""
    from refine.model.parametrize import infeasibility
    from refine.optimize.levenberg_marquardt import minimise

    rng = np.random.default_rng(5)
    geo = _ellipse_geometry(rng)
    target = -rng.uniform(1, 4)  # the smaller semi-axis pulled below zero

    def residuals(z):
        p = geo.shape_params(z)[0]
        return np.array([min(p[2], p[3]) - target, p[0] - 50.0, p[1] - 30.0])

    def jacobian(z, step=1e-7):
        r0 = residuals(z)
        return np.stack([(residuals(z + step * e) - r0) / step for e in np.eye(z.size)], 1)

    seen = []
    res = minimise(residuals, jacobian, geo, np.zeros(geo.size), max_steps=40,
                   on_evaluation=lambda z, c: seen.append(np.array(z)))
    for z in seen:
        assert infeasibility(geo, z) is None
        assert geo.shape_params(z)[0, 2:4].min() > geo.min_axis
    p = geo.shape_params(res.values["z"])[0]
    assert geo.min_axis < p[2:4].min() < geo.params0[0, 2:4].min() - 1.0  # driven towards zero, never past
    # the parametrisation itself refuses the step past it, and says why
    z = np.zeros(geo.size)
    z[2:4] = -p[2:4].max() / geo.scale * 1.5
    assert "semi-axis" in infeasibility(geo, z)


def test_log_moduli_are_bounded_and_their_exp_never_overflows():
    from refine.model.parametrize import MAX_LOG_RATIO, RegionModuli, bounded_exp, infeasibility
    from refine.optimize.levenberg_marquardt import minimise

    rng = np.random.default_rng(9)
    moduli = RegionModuli(np.ones((1, 4)), 10.0)
    assert infeasibility(moduli, [rng.uniform(-5, 5)]) is None
    assert infeasibility(moduli, [MAX_LOG_RATIO * rng.uniform(1.1, 3)]) is not None
    assert infeasibility(moduli, [np.nan]) is not None
    far = 800.0 + 100 * rng.uniform()  # a draw far beyond any fit
    with np.errstate(over="raise"):
        assert np.isfinite(bounded_exp([far, -far])).all()
    # a fit that runs away in the log modulus stops at the bound
    seen = []
    res = minimise(lambda z: np.array([z[0] - 1e4]), lambda z: np.array([[1.0]]), moduli, np.zeros(1),
                   on_evaluation=lambda z, c: seen.append(float(z[0])))
    assert max(abs(v) for v in seen) <= MAX_LOG_RATIO and abs(res.values["z"][0]) <= MAX_LOG_RATIO


def test_quantities_of_a_draw_past_a_vanishing_axis_are_numbers():
    """A draw of the fitted unknowns (the error bars' sampling) may cross an axis through zero: its
    quantities are the signed continuation, and a feasible shape's are as before."""
    from refine.diagnosis.uncertainty import shape_quantities

    rng = np.random.default_rng(2)
    a, b = rng.uniform(2, 6, 2)
    ok = RegionShape((1.0, 2.0), (a, b), 0.3, "ellipse", 2.0)
    bad = replace(ok, axes=(a, -b))
    rect = RegionShape((1.0, 2.0), (-a, b), 0.3, "rectangle", 2.0)
    q = shape_quantities([ok, bad, rect])
    assert q[0, 5] == pytest.approx(ok.outline()[0])
    assert q[1, 5] == pytest.approx(-np.pi * a * b) and q[2, 5] == pytest.approx(-4 * a * b)
    assert np.isfinite(q).all()


# ------------------------------------------------------------------- a failed hypothesis is a row
@dataclass(frozen=True)
class _Fake:
    cause: str
    chi2_fit: float
    shapes: tuple = ()
    law: str = "neo-hookean"
    k: int = 4

    @property
    def bic(self):
        return self.chi2_fit + 10.0

    chi2_holdout = 50.0

    def describe(self):
        return f"{self.cause} (fake)"


KINDS = ("regions", "hole", "rectangle", "ellipse remeshed", "law", "hole with law")


@pytest.mark.parametrize("failing", KINDS)
def test_each_hypothesis_kind_that_fails_is_a_row_and_the_others_still_run(monkeypatch, failing):
    import refine.causes as causes
    from refine.diagnosis import search
    from refine.diagnosis.laws import ALTERNATIVE_LAWS

    law = next(k for k, v in ALTERNATIVE_LAWS.items() if v)
    ran = []
    rng = np.random.default_rng(KINDS.index(failing))
    message = f"forced failure {rng.integers(1000)}"

    def job(kind, result):
        def f(*args, **kwargs):
            ran.append(kind)
            if kind == failing:
                raise ValueError(message)
            return result
        return f

    soft = RegionShape((5.0, 5.0), (3.0, 2.0), 0.1, "ellipse", 0.5)
    region = _Fake("softer-region", 300.0, (soft,))
    monkeypatch.setattr(causes.region, "fit_regions", job("regions", region))
    monkeypatch.setattr(causes.hole, "fit_hole", job("hole", _Fake("hole", 400.0, (soft,))))
    monkeypatch.setattr(causes.rectangle, "fit_rectangle", job("rectangle", _Fake("softer-region", 350.0, (soft,))))
    monkeypatch.setattr(causes.rectangle, "refit_ellipse",
                        job("ellipse remeshed", _Fake("softer-region", 290.0, (soft,))))
    monkeypatch.setattr(causes.law, "fit_law", job("law", _Fake("material-law", 320.0)))
    monkeypatch.setattr(causes.hole_in_law, "hole_law_jobs",
                        lambda model, out, *a: {"hole with law": job("hole with law", _Fake("hole", 310.0, (soft,)))})
    cfg = DiagnoseConfig(try_rectangles=True, try_laws=True)
    model = SimpleNamespace(experiment=SimpleNamespace(law=law), spacing=1.0)
    cand = SimpleNamespace(centroid=(5.0, 5.0), axes=(3.0, 2.0), angle=0.1, sign=-1, source="field")
    with ThreadPoolExecutor(2) as pool:
        trials = search.Trials(model, None, None, 1.0, cfg, SimpleNamespace(propagation=0.0), 10,
                               lambda m: None, pool)
        out = search._try_hypotheses(trials, [cand])
    rows = [f.row() for f in trials.failed]
    assert len(rows) >= 1 and all(r["failed"] == {"error": "ValueError", "message": message} for r in rows)
    assert all(r["bic"] is None for r in rows)
    expected = {"regions": "region", "hole": "hole", "rectangle": "region", "ellipse remeshed": "region",
                "law": "material-law", "hole with law": "hole"}[failing]
    assert {r["cause"] for r in rows} == {expected}
    # the others ran (a rectangle and the remeshed ellipse start from the fitted ellipse: not without it)
    others = {"hole", "law"} | ({"rectangle", "ellipse remeshed"} if failing != "regions" else set())
    assert others - {failing} <= set(ran)
    assert len(out) >= 2


# ---------------------------------------------------------------- atomic writes
def test_a_write_that_fails_midway_leaves_the_old_file_and_no_partial_one(tmp_path):
    rng = np.random.default_rng(4)
    old = f"old {rng.integers(10**6)}\n"
    path = tmp_path / "report.json"
    atomic.write_text(path, old)
    with pytest.raises(RuntimeError):
        with atomic.replacing(path) as tmp:
            tmp.write_text("half of a new fi")
            raise RuntimeError("killed mid-write")
    assert path.read_text() == old
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report.json"]

    class Breaks:  # a figure whose saving fails after some bytes
        def savefig(self, f, **kw):
            open(f, "wb").write(b"\x89PNG half")
            raise OSError("disk full")

    with pytest.raises(OSError):
        atomic.save_figure(Breaks(), tmp_path / "residuals.png")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report.json"]

    (tmp_path / "paraview").mkdir()
    (tmp_path / "paraview" / "a.pvd").write_text(old)
    with pytest.raises(KeyboardInterrupt):
        with atomic.folder(tmp_path / "paraview") as tmp:
            (tmp / "a.pvd").write_text("half")
            raise KeyboardInterrupt
    assert (tmp_path / "paraview" / "a.pvd").read_text() == old
    with atomic.folder(tmp_path / "paraview") as tmp:
        (tmp / "b.pvd").write_text("new")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["paraview", "report.json"]
    assert [p.name for p in (tmp_path / "paraview").iterdir()] == ["b.pvd"]


# ----------------------------------------------- a failure after the initial model: a report still
@pytest.fixture(scope="module")
def homogeneous(tmp_path_factory):
    from refine.bundle import write_bundle
    from refine.demo_data import Truth, synthetic_bundle

    root = tmp_path_factory.mktemp("robust") / "bundle"
    write_bundle(root, synthetic_bundle(Truth(), seed=31, spacing=10.0, noise=0.02, fractions=(1.0,), name="plain"))
    return root


def _outputs(out):
    r = json.loads((out / "report.json").read_text())
    return r, (out / "summary.txt").read_text(), (out / "report.html").read_text()


def test_a_failing_figure_still_writes_the_report_and_exits_non_zero(homogeneous, tmp_path, monkeypatch):
    from refine.cli.main import main
    from refine.diagnosis import report

    def broken(*a, **k):
        raise RefineError("forced: a figure cannot be drawn")

    monkeypatch.setattr(report, "figures", broken)
    out = tmp_path / "out"
    assert main(["diagnose", str(homogeneous), "--out", str(out), "--no-discretisation-error"]) != 0
    r, text, page = _outputs(out)
    assert r["incomplete"]["stage"] == "writing the report" and "figure cannot be drawn" in r["incomplete"]["message"]
    assert "baseline" in r and r["decision"]["hypotheses"]  # the finished report, with the error
    assert "stopped in writing the report" in text and "incomplete" in page
    assert not [p for p in out.iterdir() if p.name.startswith(".")]  # no temporary file left


def test_an_interrupt_after_the_initial_model_writes_what_it_has(homogeneous, tmp_path, monkeypatch):
    from refine.cli.diagnose import diagnose
    from refine.diagnosis import pipeline

    def interrupted(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(pipeline, "_errors", interrupted)
    out = tmp_path / "out"
    with pytest.raises(KeyboardInterrupt):
        diagnose(homogeneous, out, config={"discretisation_error": False}, quiet=True)
    r, text, page = _outputs(out)
    assert r["incomplete"]["error"] == "KeyboardInterrupt" and r["incomplete"]["stage"] == "the errors and forces"
    assert r["decision"]["hypotheses"][0]["cause"] == "none"  # the initial model's row
    assert r["decision"]["p_value"] > 0 and "KeyboardInterrupt" in text


@pytest.fixture(scope="module")
def inclusion(tmp_path_factory):
    from refine.bundle import write_bundle
    from refine.demo_data import Inclusion, Truth, synthetic_bundle

    rng = np.random.default_rng(8)
    truth = Truth(inclusions=(Inclusion(jf.Ellipse(rng.uniform(60, 80), 38.0, 14.0, 10.0, 0.4), ratio=6.0),))
    root = tmp_path_factory.mktemp("robust") / "inclusion"
    write_bundle(root, synthetic_bundle(truth, seed=8, spacing=8.0, noise=0.02, fractions=(1.0,), name="inclusion"))
    return root


@pytest.mark.slow  # a real search (about a minute on 2 cores); the fast tests above fake the fits
def test_a_failure_in_the_final_fit_writes_the_rows_so_far_and_exits_non_zero(inclusion, tmp_path, monkeypatch):
    """The search's rows (a fitted region, a failed rectangle with its reason) survive a failure in
    the chosen model's refit."""
    from refine.causes import rectangle
    from refine.cli.main import main
    from refine.diagnosis import pipeline

    def no_rectangle(*a, **k):
        raise ValueError("forced: no rectangle")

    def no_refit(*a, **k):
        raise jf.exceptions.MeshError("forced: an ellipse needs positive semi-axes")

    monkeypatch.setattr(rectangle, "fit_rectangle", no_rectangle)
    monkeypatch.setattr(pipeline, "_refit_on_every_frame", no_refit)
    out = tmp_path / "out"
    status = main(["diagnose", str(inclusion), "--out", str(out), "--max-regions", "1", "--no-laws",
                   "--try-rectangles", "yes", "--seed", "3"])
    assert status != 0
    r, text, page = _outputs(out)
    assert r["incomplete"]["stage"] == "the refit on every frame" and r["incomplete"]["error"] == "MeshError"
    rows = r["decision"]["hypotheses"]
    assert rows[0]["cause"] == "none" and any(h["cause"] == "stiffer-region" and h["bic"] is not None for h in rows)
    failed = [h for h in rows if h.get("failed")]
    assert {h["tried"] for h in failed} == {"rectangle", "rectangle turned"}
    assert all(h["failed"]["message"] == "forced: no rectangle" for h in failed)
    assert "rectangle failed (ValueError: forced: no rectangle)" in text and "no rectangle" in page


def test_error_bars_of_a_poorly_fixed_region_are_drawn_without_error():
    """The crash of the real plates: the error bars' draws of a region the data barely fix cross
    a semi-axis through zero and a log ratio far past any fit (was: "an ellipse needs positive
    semi-axes", after "overflow encountered in exp")."""
    from refine.diagnosis.uncertainty import sampled_variance
    from refine.model.parametrize import bounded_exp

    rng = np.random.default_rng(12)
    geo = _ellipse_geometry(rng)

    class Hyp:  # as refine.diagnosis.regions.Regions.shapes_at: the log ratio, then the geometry
        def shapes_at(self, compiled, z):
            g = geo.shape_params(z[1:])[0]
            return (RegionShape((g[0], g[1]), (g[2], g[3]), g[4], "ellipse", float(bounded_exp(z[0]))),)

    z = np.zeros(1 + geo.size)
    cov = np.diag([900.0**2, 1.0, 1.0, *(rng.uniform(3, 6, 3) ** 2)])  # axes and ratio barely fixed
    fitted = SimpleNamespace(z=z, hypothesis=Hyp(), compiled=None, shapes=Hyp().shapes_at(None, z))
    with np.errstate(over="raise"):
        var = sampled_variance(fitted, cov, draws=200)
    assert var.shape == (1, 7) and np.all(np.isfinite(var[:, :6]))
