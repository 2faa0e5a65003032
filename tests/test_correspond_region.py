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
