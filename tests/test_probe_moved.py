"""A probe moved with a morphed mesh interpolates, not extrapolates, where a point left its cell."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxfem.mesh import Mesh
from jaxfem.mesher import plate
from jaxfem.probe import locate
from jaxfem.shapes import Ellipse, morph, morph_nodes


@pytest.mark.parametrize("element", ["tri3", "tri6"])
def test_moved_probe_finds_the_cell_a_point_moved_into(element):
    """Morph a hole's ellipse far enough that many points change cells: the moved probe gives the
    same values of a non-linear nodal field as a probe located afresh on the morphed mesh."""
    rng = np.random.default_rng(11)
    e = Ellipse(*rng.uniform([45, 27], [55, 33]), *rng.uniform(7, 9, 2), rng.uniform(0, np.pi))
    m = plate(0, 0, 100, 60, 4.0, inclusions=[e], element=element)
    mo = morph(m, [e])
    pts = rng.uniform([5, 5], [95, 55], (400, 2))
    probe = locate(m, pts)
    new = jnp.asarray(e.params[None] + np.array([[2.5, -2.0, 2.0, 1.5, 0.2]]))
    X = np.asarray(morph_nodes(mo.nodes0, new, mo.params0, mo.weights))
    fresh = locate(Mesh(X, m.cells, m.element), pts)
    left = np.flatnonzero(np.asarray(fresh.cells) != probe.cells)
    assert left.size > 10  # the test moves points across cells
    field = np.sin(m.nodes / 9.0) * np.cos(m.nodes[:, ::-1] / 13.0)  # a curved field on the nodes
    moved = probe.moved(jnp.asarray(X), pts)
    assert np.abs(np.asarray(moved(field)) - np.asarray(fresh(field))).max() < 1e-9
    assert np.array_equal(np.asarray(moved.cells), np.asarray(fresh.cells))

    def f(q):  # still differentiable through the morph
        return jnp.sum(probe.moved(morph_nodes(mo.nodes0, q, mo.params0, mo.weights), pts)(field))

    d, h = jnp.asarray(rng.standard_normal((1, 5)) * [1, 1, 1, 1, 0.05]), 1e-5
    fd = (f(new + h * d) - f(new - h * d)) / (2 * h)
    assert abs(float(jnp.sum(jax.grad(f)(new) * d)) - float(fd)) <= 1e-6 * max(1.0, abs(float(fd)))
