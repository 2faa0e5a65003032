"""Roles of points (refine.bundle.roles): outer ring is boundary, a seeded fraction of the interior validates."""

import numpy as np
import pytest

from refine.bundle import ROLES, assign_roles
from refine.exceptions import ObservationError


def _lattice(rows, cols, hole=None):
    ii, jj = np.mgrid[0:rows, 0:cols]
    keep = np.ones((rows, cols), bool)
    if hole is not None:
        keep[hole] = False
    index = np.stack([ii[keep], jj[keep]], axis=1)
    xy = index[:, ::-1] * 12.0 + 5.0
    return xy, index


def test_outer_ring_of_grid_topology_is_boundary_and_holes_are_not():
    xy, index = _lattice(8, 10, hole=(slice(3, 5), slice(4, 6)))
    roles = assign_roles(xy, validate_fraction=0.25, seed=1, grid_index=index)
    ring = (index[:, 0] == 0) | (index[:, 0] == 7) | (index[:, 1] == 0) | (index[:, 1] == 9)
    assert np.all(roles[ring] == "boundary")
    assert not np.any(roles[~ring] == "boundary")
    interior = np.count_nonzero(~ring)
    assert np.count_nonzero(roles == "validate") == round(0.25 * interior)
    assert set(roles) == {"boundary", "guide", "validate"}


def test_concave_outline_follows_topology():
    xy, index = _lattice(6, 6, hole=(slice(0, 3), slice(3, 6)))    # an L shape
    roles = assign_roles(xy, 0.0, grid_index=index)
    inner_corner = np.nonzero((index[:, 0] == 3) & (index[:, 1] == 3))[0][0]
    assert roles[inner_corner] == "boundary"
    assert roles[np.nonzero((index[:, 0] == 2) & (index[:, 1] == 2))[0][0]] == "boundary"
    assert roles[np.nonzero((index[:, 0] == 4) & (index[:, 1] == 1))[0][0]] == "guide"


def test_convex_hull_without_topology_and_seeded_draw():
    rng = np.random.default_rng(0)
    xy, _ = _lattice(7, 7)
    xy = xy + rng.normal(0, 0.5, xy.shape)
    roles = assign_roles(xy, 0.3, seed=5)
    assert np.count_nonzero(roles == "boundary") >= 20
    again = assign_roles(xy, 0.3, seed=5)
    other = assign_roles(xy, 0.3, seed=6)
    assert (roles == again).all() and not (roles == other).all()


def test_bad_fraction_raises():
    xy, index = _lattice(4, 4)
    with pytest.raises(ObservationError, match="validate_fraction"):
        assign_roles(xy, 1.5)
    with pytest.raises(ValueError):  # as before, when tracking raised it
        assign_roles(xy[:, :1])


def test_one_roles_registry():
    import refine.bundle.io
    import refine.bundle.observations
    import tracking

    assert ROLES == ("boundary", "guide", "validate")
    assert refine.bundle.observations.ROLES is ROLES and refine.bundle.io.ROLES is ROLES
    assert not hasattr(tracking, "ROLES") and not hasattr(tracking, "assign_roles")
