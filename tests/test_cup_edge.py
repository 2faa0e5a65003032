"""The painted grid's evidence of a cup holder's hidden hole (refine.solid.edge): the lattice of the
bottom's crossings found at any angle under noise, the gap of missing crossings that brackets the
hole's edge (the true hole consistent with it, the ellipse between the two sets near it), crossings
lost at the rim or out of view taken for no hole, and the fit's constraint."""

import numpy as np
import pytest

import jaxfem as jf
from examples.cup_holder import cup_bottom, cup_holder
from refine.solid.edge import EdgeGeometry, NoLattice, evidence_near, grid_lattice
from refine.solid.morph import ExtrudedMorph
from examples.cup_holder.synthetic import CupGeometry, _points, random_hole

G = CupGeometry()


def bottom(seed, hole=True, spacing=1.2):
    """The bottom's crossings (cup frame, noisy by 0.01 mm as tracked) and the hole drawn under ``seed``."""
    truth = random_hole(G, seed) if hole else None
    rng = np.random.default_rng(seed)
    X, _ = _points(G, truth, spacing, rng)
    xy = X[np.abs(X[:, 2]) < 1e-9, :2]
    return xy + rng.normal(0, 0.01, xy.shape), truth


@pytest.mark.parametrize("seed", [11, 12])
def test_the_lattice_of_a_turned_noisy_grid_is_found(seed):
    xy, _ = bottom(seed)
    lat = grid_lattice(xy)
    assert lat.step == pytest.approx(1.2, abs=0.005)
    np.testing.assert_allclose(lat.sites(lat.index), xy, atol=0.05)
    with pytest.raises(NoLattice):
        grid_lattice(np.random.default_rng(seed).uniform(-10, 10, (200, 2)))  # scattered points: no grid


@pytest.mark.parametrize("seed", [21, 22, 23])
def test_the_missing_crossings_bracket_the_hidden_hole(seed):
    xy, truth = bottom(seed)
    lat = grid_lattice(xy)
    # a candidate's centre off by a step still finds the gap
    start = np.array([truth.cx, truth.cy]) + np.random.default_rng(seed).normal(0, 0.7, 2)
    # the synthetic bundle drops the crossings within 0.1 pitch of the hole: a tight slack holds
    ev = evidence_near(lat, start, max(truth.rx, truth.ry) + 2 * lat.step, G.r_in, slack=0.15)
    assert ev is not None and len(ev.missing) >= 3
    assert ev.violation(truth.params) == 0.0  # the truth is consistent with what the grid shows
    c = ev.ellipse
    assert np.hypot(c[0] - truth.cx, c[1] - truth.cy) < 0.5 * lat.step
    assert abs(np.pi * c[2] * c[3] / truth.area - 1) < 0.35
    lo, hi = ev.area_range()
    assert lo <= truth.area <= hi and hi - lo < truth.area  # the grid's bracket: wide, but holds the truth
    loose = evidence_near(lat, start, max(truth.rx, truth.ry) + 2 * lat.step, G.r_in)  # a tracker's slack
    assert loose.violation(truth.params) == 0.0 and loose.area_range()[0] < lo
    # the fit's constraint: a hole moved off its gap by two steps is turned down before any solve
    e = jf.Ellipse(*ev.ellipse)
    slab = cup_bottom(G.r_in, G.r_out, G.bottom, 2.5, e)
    geo = EdgeGeometry(ExtrudedMorph.of(slab), e.params[None], scale=1.0, rotate=True, edge=ev,
                       slack=max(ev.slack, ev.missing_outside(ev.ellipse) + 1e-9))  # as SolidHole.build sets it
    assert geo.infeasibility(np.zeros(5)) is None
    away = np.zeros(5)
    away[:2] = 2 * lat.step * (np.array([ev.ellipse[0], ev.ellipse[1]]) / max(np.hypot(*ev.ellipse[:2]), 1e-9) + 1e-3)
    assert "missing crossing" in geo.infeasibility(-away)


def test_crossings_lost_at_the_rim_or_out_of_view_are_no_hole():
    xy, _ = bottom(31, hole=False)
    r = np.hypot(*xy.T)
    rim = np.argmin(np.abs(r - (G.r_out - 1.0)))  # a crossing near the rim, lost
    keep = (np.arange(len(xy)) != rim) & (xy[:, 0] > -6.0)  # and the left part out of view
    lat = grid_lattice(xy[keep])
    for place in (xy[rim], [-7.0, 0.0], [-6.5, 3.0]):
        assert evidence_near(lat, place, 2.5, G.r_in) is None
    # a crossing lost inside the floor is a gap of one site, enclosed: evidence, but only of itself
    inner = np.argmin(np.hypot(*(xy - [2.0, 1.0]).T))
    lat = grid_lattice(np.delete(xy, inner, 0))
    ev = evidence_near(lat, xy[inner], 2.5, G.r_in)
    assert ev is not None and len(ev.missing) == 1 and np.hypot(*(ev.missing[0] - xy[inner])) < 0.05


def test_the_global_fit_starts_along_the_bracket_off_every_tracked_crossing(tmp_path):
    from refine.bundle.experiment import Experiment, MeshDomain
    from refine.bundle.io import Bundle
    from refine.bundle.observations import Forces, Observations
    from refine.diagnosis.shapes import Hole
    from refine.solid.diagnose import SolidConfig, grid_edge, local_recipe
    from refine.solid.start import bracket_starts

    truth = random_hole(G, 41)
    X, roles = _points(G, truth, 1.2, np.random.default_rng(41))
    jf.write_vtu(tmp_path / "mesh.vtu", cup_holder(G.r_in, G.r_out, G.height, G.bottom, 3.0).mesh)
    F = Forces(("back",), np.tile([[[0.0, 0.0, 1.0]]], (2, 1, 1)))
    obs = Observations(np.arange(1, len(X) + 1), X, roles, np.zeros((2, len(X), 3)), forces=F)
    exp = Experiment(name="cup", kind="solid", domain=MeshDomain("mesh.vtu"), law="neo-hookean", E=1.0, nu=0.4)
    _, local, _ = local_recipe(Bundle(exp, obs, root=tmp_path), SolidConfig())
    edge = grid_edge(local, Hole((truth.cx + 0.5, truth.cy), (truth.rx, truth.ry), 0.0), SolidConfig(), log=print)
    assert edge is not None and edge.slack == pytest.approx(0.75 * 1.2, rel=1e-3)
    starts = bracket_starts(local, edge)
    assert len(starts) >= 2
    areas = [np.pi * e.rx * e.ry for e in starts]
    assert areas == sorted(areas) and min(areas) < truth.area < max(areas) * 1.3  # the bracket holds the truth
    xy = local.obs.reference[:, :2]
    for e in starts:
        assert not e.contains(xy).any() and edge.missing_outside(e.params) <= edge.slack


def test_the_grids_area_bracket_searched_from_a_consistent_hole_holds_the_truth():
    xy, truth = bottom(21)
    ev = evidence_near(grid_lattice(xy), [truth.cx, truth.cy], 5.0, G.r_in, slack=0.15)
    lo, hi = ev.area_range(truth.params)  # from the truth, which is consistent
    assert lo <= truth.area <= hi


class _Wall:
    """A toy parametrisation: two unknowns kept to ``z0 + z1 <= 1`` (a hole kept off a tracked point)."""

    size, z0 = 2, np.zeros(2)

    def __init__(self, slide: bool):
        if slide:
            self.constraints = lambda z: np.array([1.0 - z[0] - z[1]])

    def infeasibility(self, z):
        return "over the wall" if z[0] + z[1] > 1.0 else None

    def values(self, z):
        return {}


@pytest.mark.parametrize("seed", [41, 42])
def test_a_step_into_a_constraint_slides_along_it(seed):
    from refine.optimize.levenberg_marquardt import minimise

    rng = np.random.default_rng(seed)
    target = np.array([1.0, 0.0]) + rng.uniform(0.5, 2.0, 2)  # beyond the wall
    W = np.diag(rng.uniform(0.5, 3.0, 2))  # unequal weights: the constrained minimum is not the projection
    res = lambda z: W @ (z - target)  # noqa: E731
    w = np.linalg.solve(W.T @ W, np.ones(2))
    best = target - w * (target.sum() - 1) / w.sum()  # the minimum on the wall
    slid = minimise(res, lambda z: W, _Wall(True), np.zeros(2), rtol=1e-12, chi2_tol=1e-12)
    np.testing.assert_allclose(slid.values["z"], best, atol=1e-5)
    stalled = minimise(res, lambda z: W, _Wall(False), np.zeros(2), rtol=1e-12, chi2_tol=1e-12)
    assert np.linalg.norm(stalled.values["z"] - best) > 1e-2  # rejected whole, the steps stop short


def test_the_hole_geometry_constraints_agree_with_its_check():
    xy, truth = bottom(24)
    lat = grid_lattice(xy)
    ev = evidence_near(lat, (truth.cx, truth.cy), max(truth.rx, truth.ry) + 2 * lat.step, G.r_in, slack=0.75)
    e = jf.Ellipse(*ev.ellipse)
    geo = EdgeGeometry(ExtrudedMorph.of(cup_bottom(G.r_in, G.r_out, G.bottom, 2.5, e)), e.params[None],
                       scale=0.6, rotate=True, outside=xy, edge=ev, slack=max(ev.slack, ev.missing_outside(e.params)))
    rng = np.random.default_rng(24)
    seen = set()
    for z in rng.normal(0, 1.0, (120, 5)):
        ok = np.min(geo.constraints(z)) >= 0
        why = geo.infeasibility(z)
        if ok:  # within the constraints: no tracked point covered, no missing crossing left out
            assert why is None or "squash" in why
        seen.add((ok, why is None))
    assert {(True, True), (False, False)} <= seen  # both sides drawn
