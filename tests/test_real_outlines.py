"""Real measurements through the model: boundary points off the drawn outline, domains built from
the points themselves, forces across named sides, noise-free data, and boundary motion that the
sheet cannot follow (issue 22, items 1 and 5).

Synthetic data come from :func:`refine.demo_data.synthetic_bundle` (a larger sheet solved on a
finer quadratic mesh, sampled with noise); irregular outlines cut the tracked grid along a random
smooth curve and move every point by random positional noise, all drawn under seeds.
"""

from __future__ import annotations

import dataclasses

import jaxfem as jf
import numpy as np
import pytest

from refine.bundle.experiment import Experiment, RectangleDomain
from refine.bundle.io import Bundle
from refine.bundle.observations import Observations
from refine.demo_data import grid_points


def _folding_bundle() -> Bundle:
    """A small sheet whose right edge is carried past its left edge in frame 2: it must fold."""
    pts = grid_points((0.0, 0.0, 10.0, 6.0), 2.0)
    on_edge = (pts[:, 0] == 0) | (pts[:, 0] == 10) | (pts[:, 1] == 0) | (pts[:, 1] == 6)
    roles = np.where(on_edge, "boundary", "guide")
    stretch = 0.1 * pts[:, :1] * np.array([1.0, 0.0])  # frame 1: 10 % stretch, fine
    fold = -1.6 * pts[:, :1] * np.array([1.0, 0.0])  # frame 2: x -> -0.6 x, the sheet turned inside out
    disp = np.stack([stretch, np.where(on_edge[:, None], fold, stretch)])
    ex = Experiment("fold", "plane-stress", RectangleDomain(0.0, 0.0, 10.0, 6.0), "neo-hookean", 1.0, 0.3,
                    thickness=1.0, noise_std=0.01)
    return Bundle(ex, Observations(np.arange(1, len(pts) + 1), pts, roles, disp))


def test_boundary_motion_that_folds_the_sheet_stops_diagnose_before_any_fit(recwarn):
    from refine.diagnosis import diagnose

    lines = []
    with pytest.raises(jf.SolverError, match=r"frame 2 of 2.*nonlinear solve failed at load step"):
        diagnose(_folding_bundle(), log=lines.append)
    assert not any("misfit" in line or "tried" in line for line in lines), lines  # nothing was fitted
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)]


# ------------------------------------------------------------------ outlines from the points
def _cut(points: np.ndarray, rng, spacing: float, roi=(20.0, 10.0, 120.0, 70.0)):
    """Keep the grid points right of a random smooth curve x = left(y) (up to 6 spacings in):
    an irregular left edge, the other three straight. Returns the mask and the (row, col) index."""
    x0, y0, x1, y1 = roi
    amp, phase = rng.uniform(-1.0, 1.0, 3), rng.uniform(0, 2 * np.pi, 3)
    t = np.pi * (points[:, 1] - y0) / (y1 - y0)
    left = x0 + spacing * (3.0 + sum(3.0 * amp[k] / (k + 1) * np.sin((k + 1) * t + phase[k]) for k in range(3)))
    index = np.round((points - [x0, y0]) / spacing).astype(int)[:, ::-1]
    return points[:, 0] >= left, index


def _irregular(bundle: Bundle, rng, jitter: float) -> Observations:
    """``bundle``'s grid cut along a random curve, boundary = the lattice's outer outline (as
    ``nonrigid track`` marks it), every position moved by Gaussian noise of std ``jitter``."""
    from refine.bundle.from_tracks import lattice_outline

    obs = bundle.observations
    keep, index = _cut(obs.reference, rng, 5.0)
    ring = np.zeros(int(keep.sum()), bool)
    ring[lattice_outline(index[keep])] = True
    roles = np.where(ring, "boundary", np.where(obs.roles[keep] == "validate", "validate", "guide"))
    reference = obs.reference[keep] + rng.normal(0.0, jitter, (int(keep.sum()), 2))
    return Observations(obs.ids[keep], reference, roles, obs.displacements[:, keep], obs.forces)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_concave_outline_passes_through_every_boundary_point(seed):
    """The points' concave outline of a grid cut along a random curve, positions noisy: every
    boundary point is a vertex, every point inside or on it, its area that of the cut region
    within a cell's worth along the ragged edge."""
    from matplotlib.path import Path

    from refine.bundle.outline import outline_of_points

    rng = np.random.default_rng(seed)
    pts = grid_points((20.0, 10.0, 120.0, 70.0), 5.0)
    keep, index = _cut(pts, rng, 5.0)
    from refine.bundle.from_tracks import lattice_outline

    cut = pts[keep] + rng.normal(0.0, 0.2, (int(keep.sum()), 2))
    boundary = np.zeros(len(cut), bool)
    boundary[lattice_outline(index[keep])] = True
    poly = outline_of_points(cut, boundary, "concave")
    assert {tuple(p) for p in cut[boundary]} <= {tuple(p) for p in poly}
    ring = pts[keep][lattice_outline(index[keep])]  # the lattice's own outline, exact positions

    def area(loop):
        return 0.5 * abs(np.sum(loop[:, 0] * np.roll(loop[:, 1], -1) - np.roll(loop[:, 0], -1) * loop[:, 1]))

    assert abs(area(poly) / area(ring) - 1) < 0.01, (area(poly), area(ring))
    on = np.array([tuple(p) in {tuple(q) for q in poly} for p in cut])
    assert (Path(poly).contains_points(cut) | on).all()
    # a guide point far outside a given outline is refused, naming it
    from refine.exceptions import ObservationError

    stray = np.vstack([cut, [[200.0, 40.0]]])
    with pytest.raises(ObservationError, match="apart from the others"):
        outline_of_points(stray, np.append(boundary, False), "concave", ids=np.arange(1, len(stray) + 1))


# ------------------------------------------------------------------ forces across named sides
@pytest.fixture(scope="module")
def pulled():
    """A homogeneous sheet with the force across the tracked region's right side (x = 120 mm),
    and an initial model whose modulus is off by a random factor (drawn under the seed)."""
    from refine.demo_data import Truth, synthetic_bundle

    rng = np.random.default_rng(2207)
    truth = Truth()
    bundle = synthetic_bundle(truth, seed=2207, spacing=5.0, noise=0.02, fractions=(0.5, 1.0), h=3.0, forces=True)
    wrong = dataclasses.replace(bundle.experiment, E=truth.E * rng.uniform(0.5, 2.0))
    return truth, dataclasses.replace(bundle, experiment=wrong), rng


def _modulus(bundle: Bundle):
    """The background modulus a measured force gives the bundle's initial model, and the model."""
    from refine.diagnosis.forces import force_scale
    from refine.model.measured import MeasuredModel

    model = MeasuredModel(bundle.experiment, bundle.observations)
    scale = force_scale(model, model.params())
    return bundle.experiment.E * scale.scale, scale, model


def test_a_force_on_a_named_side_of_the_points_outline_gives_the_modulus(pulled, tmp_path):
    """Irregular measured outline (a random cut, noisy positions), domain from the points, the
    force on a named side: the absolute modulus within 3 %; a force on "right" of such a domain
    is an error that says what to write, in memory and in a bundle read from disk."""
    from refine.bundle.experiment import FromPointsDomain
    from refine.bundle.observations import Forces

    truth, bundle, rng = pulled
    obs = _irregular(bundle, rng, jitter=0.1)
    grip = dataclasses.replace(obs, forces=Forces(("grip",), obs.forces.values))
    domain = FromPointsDomain("concave", sides=(("grip", (120.0, 10.0), (120.0, 70.0)),))
    named = Bundle(dataclasses.replace(bundle.experiment, domain=domain), grip)
    E, scale, model = _modulus(named)
    assert E == pytest.approx(truth.E, rel=0.03) and scale.relative_residual < 0.03, (E, truth.E, scale)
    x = model.mesh.nodes[model.sides["grip"], 0]
    assert len(x) >= 60 / model.h and np.all(x > 119.0)  # the grip's nodes from bottom to top, no other side's
    guide = obs.mask("guide")
    pred = np.asarray(model.predict(model.params()))[:, guide]
    assert np.sqrt(np.mean((pred - obs.displacements[:, guide]) ** 2)) < 3 * 0.02  # driven right

    from refine.exceptions import BundleError, ObservationError
    from refine.bundle.io import read_bundle, write_bundle
    from refine.model.measured import MeasuredModel

    polygon = dataclasses.replace(model.experiment.domain, sides=())  # the same outline, no side named
    right = Bundle(dataclasses.replace(bundle.experiment, domain=polygon), obs)  # forces.csv says "right"
    with pytest.raises(ObservationError, match=r"unknown edge 'right'.*sides = \{ right = \[\[x0, y0\]"):
        MeasuredModel(right.experiment, right.observations)
    with pytest.raises(ObservationError, match="unknown edge 'right'"):
        write_bundle(tmp_path / "refused", right)
    path = write_bundle(tmp_path / "named", named)  # reads back as written
    back = read_bundle(path)
    assert back.experiment == named.experiment and back.observations.forces.edges == ("grip",)
    assert "from_points" in (path / "experiment.toml").read_text()
    (path / "forces.csv").write_text((path / "forces.csv").read_text().replace("grip", "right"))
    with pytest.raises(BundleError, match=r"forces.csv:2: unknown edge 'right'.*sides are \['grip'\]"):
        read_bundle(path)


def test_boundary_points_off_a_rectangle_drive_it_within_the_tolerance(pulled):
    """Boundary points moved off the rectangle by random offsets up to a tenth of the spacing (as a
    real specimen's edge): accepted, the force on "right" still gives the modulus within 3 %; one
    point moved beyond the tolerance is an error naming it and its distance."""
    from refine.exceptions import ObservationError
    from refine.model.boundary import outline_tolerance
    from refine.model.measured import MeasuredModel

    truth, bundle, rng = pulled
    obs = bundle.observations
    b = obs.mask("boundary")
    moved = obs.reference.copy()
    moved[b] += rng.uniform(-0.5, 0.5, (int(b.sum()), 2))  # up to 0.1 spacing each way, in or out
    off = dataclasses.replace(bundle, observations=dataclasses.replace(obs, reference=moved))
    E, scale, model = _modulus(off)
    assert E == pytest.approx(truth.E, rel=0.03), (E, truth.E)
    assert 0.3 < model.placement.offsets.max() <= outline_tolerance(5.0, 0.02)
    far = moved.copy()
    k = int(rng.choice(np.flatnonzero(b & (obs.reference[:, 1] == 10.0) & (obs.reference[:, 0] > 25.0))))
    far[k] = obs.reference[k] - [0.0, 2.0]  # 2 mm below the bottom edge: 1.6 x the tolerance
    with pytest.raises(ObservationError, match=rf"the farthest, point {obs.ids[k]}, is 2 away \(allowed: 1.25"):
        MeasuredModel(bundle.experiment, dataclasses.replace(obs, reference=far))


@pytest.mark.parametrize("domain,message", [
    ({"from_points": "wobbly"}, r"from_points must be one of \['concave', 'convex'\]"),
    ({"rectangle": [0, 0, 10, 6], "max_edge": 2.0}, "max_edge goes with from_points"),
    ({"rectangle": [0, 0, 10, 6], "sides": {"grip": [[10, 0]]}}, "must list two ends"),
    ({"rectangle": [0, 0, 10, 6], "sides": {"grip": [[10, 0], "top"]}}, r"grip\[1\] must be a position"),
    ({"rectangle": [0, 0, 10, 6], "sides": {"grip": [1, 2]}}, "vertex index 1 is only for a polygon"),
    ({"polygon": [[0, 0], [10, 0], [0, 6]], "sides": {"grip": [1, 3]}}, "out of range"),
    ({"mesh": "m.msh", "sides": {"grip": [[0, 0], [1, 1]]}}, "sides goes with a rectangle"),
])
def test_domain_sides_and_outlines_in_experiment_toml_are_checked(domain, message):
    from refine.exceptions import ExperimentError

    data = {"experiment": {"name": "x"}, "model": {"kind": "plane-stress", "domain": domain},
            "material": {"law": "neo-hookean", "E": 1.0, "nu": 0.3}}
    with pytest.raises(ExperimentError, match=message):
        Experiment.from_toml(data)


def test_noise_std_zero_is_a_standard_deviation():
    data = {"experiment": {"name": "x"}, "model": {"kind": "plane-stress", "domain": {"from_points": "convex"}},
            "material": {"law": "neo-hookean", "E": 1.0, "nu": 0.3}, "measurement": {"noise_std": 0.0}}
    ex = Experiment.from_toml(data)
    assert ex.noise_std == 0.0 and Experiment.from_toml(ex.to_toml()) == ex


# ------------------------------------------------------------------ noise-free data, the evidence line
def _noise_free(cause: str, seed: int) -> tuple:
    from refine.demo_data import random_truth, synthetic_bundle

    truth = random_truth(np.random.default_rng(seed), cause)
    bundle = synthetic_bundle(truth, seed=seed, spacing=5.0, noise=0.0, fractions=(0.5, 1.0), h=3.0)
    return truth, dataclasses.replace(bundle, experiment=dataclasses.replace(bundle.experiment, noise_std=0.0))


def test_noise_free_data_meet_a_null_level_of_discretisation_error_alone():
    """noise_std = 0: the null level is the model's discretisation error alone. The initial model
    of a homogeneous sheet (data from a finer quadratic mesh) stands; with a hidden stiff region
    (drawn under the seed) the null test rejects it, so the diagnosis goes on to name a cause
    (the slow test below runs it to the finding)."""
    from refine.diagnosis import DiagnoseConfig, diagnose

    _, bundle = _noise_free("none", 2211)
    d = diagnose(bundle, log=lambda m: None)
    assert d.findings == [] and d.null.sigma == 0.0 and d.null.sigma_model > 0, d.null
    assert d.null.p_value > DiagnoseConfig().alpha
    _, hidden = _noise_free("stiffer-region", 2212)
    decided = diagnose(hidden, DiagnoseConfig(alpha=0.0), log=lambda m: None)  # alpha 0: stop at the decision
    assert decided.null.p_value < DiagnoseConfig().alpha and decided.null.sigma == 0.0


def test_the_evidence_line_quotes_the_bics_of_the_hypotheses_table():
    """The user's case: BIC 7837 (initial model) -> 7641 (another law, as scored beside the other
    hypotheses); the law's refit on every guide point sums over more points (9462). The evidence
    says 7837 -> 7641, a drop of 196, not -1625."""
    from types import SimpleNamespace as S

    from refine.diagnosis.pipeline import Diagnosis

    base = S(bic=7837.2, chi2_holdout=2600.0, cause="none")
    law = S(bic=7641.4, chi2_holdout=2550.0, cause="material-law")
    refit = S(bic=9462.0, chi2_holdout=1900.0, cause="material-law")
    d = Diagnosis(None, S(ratio=12.4, p_value=0.0), base, refit, [base, law], [], None, None, selected=law)
    assert "material-law lowers BIC from 7837 to 7641 (by 196) and the held-out guide misfit from 2600 to 2550" \
        in d._evidence()
    hole = S(bic=9000.0, chi2_holdout=1800.0, cause="hole")  # a soft region renamed a hole after its refit
    d = Diagnosis(None, S(ratio=3.0, p_value=0.0), base, hole, [base, law], [], None, None,
                  selected=S(bic=7000.0, chi2_holdout=2000.0, cause="softer-region"))
    assert d._evidence().endswith("softer-region lowers BIC from 7837 to 7000 (by 837) and the held-out guide "
                                  "misfit from 2600 to 2000; refitted on every guide point as hole")


@pytest.mark.slow  # a full diagnosis (~8 min at load 34 on 2 cores; ratio 3.13 vs 3.20 at seed 11)
def test_noise_free_hidden_region_is_found_and_the_evidence_quotes_the_reported_bics():
    """noise_std = 0 with a hidden stiff region (drawn under the seed): a finding near it; the
    evidence line's BICs are the baseline's and the chosen hypothesis's in report.json's table,
    and its drop is their difference."""
    import re

    from refine.diagnosis import diagnose

    truth, bundle = _noise_free("stiffer-region", 2212)
    d = diagnose(bundle, log=lambda m: None)
    [f] = d.findings
    inc = truth.inclusions[0]
    assert f["cause"] == "stiffer-region", d.chosen.describe()
    assert np.hypot(*(np.asarray(f["region"]["centroid"]) - inc.shape.params[:2])) < 0.03 * np.hypot(100, 60)
    table = d.report()["decision"]["hypotheses"]
    m = re.search(r"lowers BIC from (-?\d+) to (-?\d+) \(by (-?\d+)\)", f["evidence"])
    assert m, f["evidence"]
    before, after, drop = map(int, m.groups())
    assert before == round(table[0]["bic"]) and table[0]["cause"] == "none"
    assert after in [round(h["bic"]) for h in table[1:]] and abs(drop - (table[0]["bic"] - after)) <= 1
    assert drop > 0


@pytest.mark.parametrize("seed", [5, 7])
def test_the_mesh_of_a_noisy_points_outline_has_one_outer_loop(seed):
    """Noisy collinear points on the outline of the points meshed by jaxfem's mesher: qhull
    keeps flat triangles of collinear nodes on the hull, which reversed a boundary edge (these
    seeds failed with a KeyError in boundary_loop before they were dropped)."""
    from refine.bundle.from_tracks import lattice_outline
    from refine.bundle.outline import outline_of_points
    from refine.bundle.roles import point_spacing

    rng = np.random.default_rng(seed)
    pts = grid_points((20.0, 10.0, 120.0, 70.0), 5.0)
    keep, index = _cut(pts, rng, 5.0)
    ring = np.zeros(int(keep.sum()), bool)
    ring[lattice_outline(index[keep])] = True
    ref = pts[keep] + rng.normal(0.0, 0.1, (int(keep.sum()), 2))
    mesh = jf.domain(jf.Polygon(outline_of_points(ref, ring)), 0.5 * point_spacing(ref))
    loop = jf.boundary_loop(mesh)
    assert len(loop) == len(mesh.boundary_facets())  # one closed outer loop, every boundary edge on it
    nodes, W = jf.boundary_interpolation(mesh, ref[ring], tol=1e-9)  # the boundary points lie on it
    assert np.allclose(W.sum(axis=1), 1.0)
