"""The pieces that make a 3D follow tractable and a found region exact: the facet shortlist (each
boundary point sees its k nearest facets, not all) and the soft balls a field's region is refitted
as (refine.correspond.region). The refit itself runs inside the slow follows of
tests/test_correspond_follow.py (2D) and tests/test_correspond_3d.py (3D)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

import jaxfem as jf
from refine.correspond.geometry import boundary_facets, candidate_distances, facet_distances, shortlist
from refine.correspond.region import SoftBalls


def test_a_shortlist_keeps_every_points_nearest_facet():
    """Points near a deformed tet10 block's surface (random displacement, random points drawn
    around random facets): the nearest facet over a shortlist of 16 equals the nearest over all
    facets, and the shortlist's distances are the full matrix's entries."""
    rng = np.random.default_rng(5)
    mesh = jf.box(0, 0, 0, 40, 20, 20, 4, 2, 2, element="tet10")
    x = mesh.nodes + rng.normal(0.0, 0.3, mesh.nodes.shape)
    facets = boundary_facets(mesh)
    picks = rng.integers(0, len(facets), 200)
    bary = rng.dirichlet(np.ones(3), 200)
    P = np.einsum("pk,pkd->pd", bary, x[facets[picks]]) + rng.normal(0.0, 0.5, (200, 3))
    full = np.asarray(facet_distances(jnp.asarray(P), jnp.asarray(x), jnp.asarray(facets)))
    cand = shortlist(P, x, facets, 16)
    listed = np.asarray(candidate_distances(jnp.asarray(P), jnp.asarray(x), jnp.asarray(facets), jnp.asarray(cand)))
    assert cand.shape == (200, 16) and len(facets) > 100
    np.testing.assert_allclose(listed, np.take_along_axis(full, cand, axis=1), atol=1e-12)
    np.testing.assert_allclose(listed.min(axis=1), full.min(axis=1), atol=1e-12)


def test_soft_balls_set_their_ratio_inside_and_nothing_far_away():
    rng = np.random.default_rng(6)
    centroids = rng.uniform(0, 40, (400, 3))
    balls = SoftBalls(centroids, 10.0, 1, width=0.5, scale=2.0)
    centre, radius, ratio = rng.uniform(15, 25, 3), rng.uniform(4, 7), rng.uniform(3, 8)
    z = balls.z_of(centre[None], radius, ratio)
    f = np.asarray(balls.log_factor(z))
    d = np.linalg.norm(centroids - centre, axis=1)
    np.testing.assert_allclose(f[d < radius - 3], np.log(ratio), rtol=1e-2)
    assert np.abs(f[d > radius + 3]).max() < 0.01 * np.log(ratio)
    v = balls.values(z)["ball1"]
    np.testing.assert_allclose([*v["centre"], v["radius"], v["ratio"]], [*centre, radius, ratio])
    g = jax.grad(lambda zz: jnp.sum(balls.log_factor(zz) ** 2))(jnp.asarray(z))  # moves centre, radius and ratio
    assert np.all(np.isfinite(g)) and np.all(np.abs(np.asarray(g)) > 0)


def _balls_2d(rng):
    return SoftBalls(rng.uniform(0, 100, (200, 2)), 10.0, 1, width=2.5, scale=5.0)


def test_refit_errors_add_the_discretisation_and_say_what_is_not_identified():
    """A ball with a random centre, radius and ratio under a seed and a random Hessian: the
    reported standard errors are the curvature's and the coarse refit's (over f - 1) in
    quadrature; radius and ratio whose Hessian block is nearly singular (a trade-off) come back
    as not identified (value None, the fitted number kept, the correlation and condition shown);
    a well-conditioned block gives numbers."""
    from refine.correspond.region_errors import IDENTIFIED_LOG_SE, described, statistical_covariance

    rng = np.random.default_rng(7)
    balls = _balls_2d(rng)
    centre, radius, ratio = rng.uniform(30, 70, 2), rng.uniform(5, 12), rng.uniform(3, 9)
    z = balls.z_of(centre[None], radius, ratio)
    A = rng.normal(size=(4, 4))
    H = A @ A.T + 4000.0 * np.eye(4)  # curvature per unknown: the centre known to ~0.1 mm
    dz = rng.normal(0.0, 0.01, 4)
    cov, scatter = statistical_covariance(H, misfit=50.0, n_points=100.0)
    assert scatter == 1.0  # residuals within the noise: no inflation
    good = described(balls, z, cov, dz, np.sqrt(2.0), H, scatter)[0]
    expect = np.sqrt(np.diag(cov) + (dz / (np.sqrt(2.0) - 1.0)) ** 2)
    np.testing.assert_allclose(good["centroid_se"], expect[:2] * balls.scale, rtol=1e-12)
    np.testing.assert_allclose(good["radius_se"], radius * expect[2], rtol=1e-12)
    assert good["identified"] == {"radius": True, "relative_elasticity": True}
    np.testing.assert_allclose([good["radius"], good["relative_elasticity"]], [radius, ratio])
    # log radius and log ratio traded off (a larger, softer ball alike): curvature small along r - k
    v = np.array([1.0, -1.0]) / np.sqrt(2.0)
    H2 = H.copy()
    H2[2:, 2:] = 400.0 * np.eye(2) - (400.0 - 0.05) * np.outer(v, v)
    cov2, scatter2 = statistical_covariance(H2, misfit=300.0, n_points=100.0)
    assert scatter2 == 3.0  # residuals 3x the noise's chi-square: the covariance grows with them
    bad = described(balls, z, cov2, None, None, H2, scatter2)[0]
    assert bad["radius"] is None and bad["relative_elasticity"] is None
    assert bad["log_se"]["radius"] > IDENTIFIED_LOG_SE and bad["trade_off"]["condition"] > 1e3
    assert bad["trade_off"]["log_radius_log_ratio_correlation"] < -0.99 and "not both identified" in bad["note"]
    np.testing.assert_allclose([bad["radius_fitted"], bad["relative_elasticity_fitted"]], [radius, ratio])
    assert bad["se_parts"]["discretisation"] is None and np.all(np.isfinite(bad["centroid_se"]))
    # only the ratio undetermined (flat along log ratio alone), traded off with the radius: neither reported
    w = np.array([0.1, 1.0]) / np.hypot(0.1, 1.0)
    H3 = H.copy()
    H3[2:, 2:] = 4000.0 * np.eye(2) - (4000.0 - 0.5) * np.outer(w, w)
    cov3, _ = statistical_covariance(H3, 50.0, 100.0)
    one = described(balls, z, cov3, None, None, H3, 1.0)[0]
    assert one["log_se"]["radius"] < IDENTIFIED_LOG_SE < one["log_se"]["relative_elasticity"]
    assert abs(one["trade_off"]["log_radius_log_ratio_correlation"]) > 0.9 and one["radius"] is None
    H3[2, 3], H3[3, 2], H3[3, 3] = 0.0, 0.0, 0.5  # the ratio undetermined alone, not traded off: the radius stays
    cov4, _ = statistical_covariance(H3, 50.0, 100.0)
    alone = described(balls, z, cov4, None, None, H3, 1.0)[0]
    assert alone["radius"] == radius and alone["relative_elasticity"] is None


def test_coarser_models_for_the_discretisation_estimate():
    """A meshed 2D domain is meshed again sqrt(2) coarser; a given block is remade with fewer
    bricks of the same element; a given mesh that does not fill its bounding box has none."""
    from refine.bundle.experiment import Experiment, MeshDomain, RectangleDomain
    from refine.correspond.model import CloudModel, Grips

    sheet = CloudModel(Experiment(name="s", kind="plane-stress", domain=RectangleDomain(0, 0, 60, 30),
                                  law="neo-hookean", E=10.0, nu=0.3, thickness=1.0), Grips(), h=7.5)
    c = sheet.coarser()
    assert c.h == np.sqrt(2.0) * 7.5 and c.cell_size() > 1.3 * sheet.cell_size() and sheet.coarser() is c
    solid = Experiment(name="b", kind="solid", domain=MeshDomain("d.vtu"), law="neo-hookean", E=10.0, nu=0.3)
    block = CloudModel(solid, Grips(), mesh=jf.box(0, 0, 0, 40, 20, 20, 8, 4, 4, element="tet4"))
    cb = block.coarser()
    assert cb.mesh.element == "tet4" and len(cb.mesh.cells) == 6 * 6 * 3 * 3
    full = jf.box(0, 0, 0, 40, 20, 20, 4, 2, 2, element="tet4")
    keep = full.centroids()[:, 0] < 30.0
    keep |= full.centroids()[:, 2] < 10.0  # an L: the bounding box is not filled
    used = np.unique(full.cells[keep])
    renum = np.full(len(full.nodes), -1)
    renum[used] = np.arange(len(used))
    ell = jf.Mesh(full.nodes[used], renum[full.cells[keep]], "tet4")
    assert CloudModel(solid, Grips(), mesh=ell).coarser() is None


def test_balls_keep_their_place_across_cell_sizes():
    """A ball's unknowns carried from a fine mesh's SoftBalls to a coarser one's (other length
    unit) describe the same centre, radius and ratio."""
    from refine.correspond.region_errors import _converted

    rng = np.random.default_rng(8)
    fine, coarse = _balls_2d(rng), SoftBalls(rng.uniform(0, 100, (90, 2)), 10.0, 1, width=3.5, scale=7.1)
    centre, radius, ratio = rng.uniform(30, 70, 2), rng.uniform(5, 12), rng.uniform(3, 9)
    z = fine.z_of(centre[None], radius, ratio)
    zc = _converted(z, fine, coarse)
    np.testing.assert_allclose(list(coarse.values(zc)["ball1"].values())[0], centre)
    np.testing.assert_allclose(_converted(zc, coarse, fine), z, atol=1e-12)
