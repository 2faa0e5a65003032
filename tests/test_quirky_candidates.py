"""Candidates on real exports' layouts (no finite-element solve; layouts drawn under a seed by the
independent generator's sampler): gaps of a thinned or jittered lattice, a hole where a gap and a
soft candidate coincide, and an edge artefact judged against the edge's own noise."""

import numpy as np
import pytest

import jaxfem as jf
from refine.bundle.experiment import RectangleDomain
from refine.bundle.observations import Observations
from refine.diagnosis.candidates import edge_artefact, missing_point_regions, soft_gaps
from refine.diagnosis.localize import Candidate
from tests._independent2d import ROI, Effect, layout, random_effect

DOMAIN = RectangleDomain(*ROI)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_thinned_lattice_has_no_gap_of_its_own(seed):
    """A 2 mm lattice thinned at random to 30 % (and jittered) leaves empty discs of 2-3 point
    spacings by chance; none is a hole candidate (before, every one wider than 1.5 spacings was)."""
    X, *_ = layout("thinned", np.random.default_rng(seed), Effect())
    assert missing_point_regions(X, DOMAIN) == []


@pytest.mark.parametrize("seed", [4, 5])
def test_a_hole_where_a_gap_and_a_soft_candidate_coincide(seed):
    """A hole of 4-7 mm drawn at random in a thinned lattice: too narrow a gap to stand out on its
    own perhaps, but inside a softer candidate (a field's patch about it, off-centre by up to 3 mm,
    twice its size) it is proposed, centred within 2 mm; a softer patch over no gap proposes none,
    nor does a stiffer one over the hole."""
    rng = np.random.default_rng(seed)
    hole = random_effect(rng, "hole")
    hole = Effect("hole", "ellipse", hole.cx, hole.cy, max(hole.a, 4.0), max(hole.b, 4.0), hole.angle, 0.0)
    X, *_ = layout("thinned", rng, hole)
    off = rng.uniform(-3.0, 3.0, 2)
    patch = Candidate(-1, np.zeros(0, int), np.array([hole.cx, hole.cy]) + off, np.array([2 * hole.a, 1.6 * hole.b]),
                      rng.uniform(0, np.pi), 1.0, 1.0)
    found = soft_gaps(X, DOMAIN, [patch])
    assert len(found) == 1 and found[0].source == "missing-points"
    assert np.hypot(*(found[0].centroid - [hole.cx, hole.cy])) < 2.0
    away = Candidate(-1, np.zeros(0, int), np.array([hole.cx, hole.cy]) + [hole.cx < 70 and 35.0 or -35.0, 0.0],
                     np.array([8.0, 8.0]), 0.0, 1.0, 1.0)
    assert soft_gaps(X, DOMAIN, [away]) == []
    stiff = Candidate(1, patch.cells, patch.centroid, patch.axes, patch.angle, 1.0, 1.0)
    assert soft_gaps(X, DOMAIN, [stiff]) == []


def test_an_edge_artefact_is_judged_against_the_edges_own_noise():
    """Points noisier towards a free edge (the generator's "edge" layout, noise 4x at the edge): a
    candidate there whose misfit the edge's noise explains is an artefact; the same candidate
    with a true departure of 5 edge-noise levels is not, nor is an interior one."""
    rng = np.random.default_rng(7)
    roi = (20.0, 0.0, 120.0, 80.0)
    X, boundary, _, gain = layout("edge", rng, Effect(), roi)
    sigma = 0.01
    r = sigma * gain[None, :, None] * rng.standard_normal((1, len(X), 2))
    U = np.sin(X[None, :, :1] / 30.0) + r  # a smooth field plus the noise
    obs = Observations(np.arange(1, len(X) + 1), X, np.where(boundary, "boundary", "guide"), U)
    fit = ~boundary
    domain = RectangleDomain(*roi)
    at_edge = Candidate(-1, np.zeros(0, int), np.array([60.0, 4.0]), np.array([10.0, 4.0]), 0.0, 1.0, 1.0)
    assert edge_artefact(at_edge, obs, r, fit, domain, 5.0, sigma)
    there = jf.Ellipse(60.0, 4.0, 15.0, 9.0, 0.0).contains(X)
    real = r + np.where(there[None, :, None], 5 * 4 * sigma, 0.0)
    assert not edge_artefact(at_edge, obs, real, fit, domain, 5.0, sigma)
    inside = Candidate(-1, np.zeros(0, int), np.array([60.0, 40.0]), np.array([8.0, 8.0]), 0.0, 1.0, 1.0)
    assert not edge_artefact(inside, obs, r, fit, domain, 5.0, sigma)


def test_the_independent_solvers_linearisation_is_its_residuals_derivative():
    """tests/_independent2d.py's hand-derived plane-stress tangent against finite differences of
    its residual at a random deformed state (a coarse gmsh mesh with a stiff inclusion): the
    generator's Newton converges to the law's equilibrium only if the two agree."""
    import skfem

    from tests._independent2d import _forms, gmsh_mesh

    rng = np.random.default_rng(11)
    nodes, tri, inside = gmsh_mesh(Effect("stiffer-region", "ellipse", 70.0, 40.0, 12.0, 8.0, 0.4, 5.0), h=20.0)
    basis = skfem.Basis(skfem.MeshTri(nodes.T.copy(), tri.T.copy()), skfem.ElementVector(skfem.ElementTriP2()))
    E = np.repeat(np.where(inside, 5 * 83.76, 83.76)[:, None], basis.X.shape[1], axis=1)
    residual, tangent = _forms(0.3)
    u = 0.02 * rng.standard_normal(basis.N) * 10
    du = rng.standard_normal(basis.N)
    K = tangent.assemble(basis, u=basis.interpolate(u), E=E)
    eps = 1e-6
    fd = (residual.assemble(basis, u=basis.interpolate(u + eps * du), E=E)
          - residual.assemble(basis, u=basis.interpolate(u - eps * du), E=E)) / (2 * eps)
    np.testing.assert_allclose(K @ du, fd, rtol=0, atol=1e-6 * np.abs(fd).max())
