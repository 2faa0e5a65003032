"""Segmentation of a log-modulus field into candidate regions (refine.diagnosis.localize.segment)."""

import numpy as np

import jaxfem as jf
from refine.diagnosis.localize import segment


def _patch(mesh, centre, half):
    """Cells whose centroids lie in the square of half side ``half`` around ``centre``."""
    c = mesh.centroids()
    return np.flatnonzero((np.abs(c - np.asarray(centre)) < half).all(1))


def test_segment_keeps_a_patch_of_exactly_the_smallest_area():
    # the 100 x 60 mesh of 5 mm squares the diagnosis fits its field on at 10 mm tracking spacing:
    # its triangles' areas are 12.499999999999998, so the four around a node sum to just under
    # the 50 mm^2 (half a grid square) a candidate needs; two random two-region cases had lost
    # their second region to that rounding
    mesh = jf.rectangle(0.0, 0.0, 100.0, 60.0, 20, 12)
    rng = np.random.default_rng(7)
    z = 0.02 * rng.standard_normal(mesh.n_cells)
    stiff, soft = _patch(mesh, (30.0, 30.0), 5.0), _patch(mesh, (65.0, 30.0), 2.5)
    assert len(soft) == 4 and mesh.volumes()[soft].sum() < 50.0
    z[stiff] += 0.9
    z[soft] -= 1.3
    found = segment(mesh, z, min_area=50.0)
    assert [c.sign for c in found] == [1, -1]  # the larger patch is the stronger one
    assert np.allclose(found[1].centroid, (65.0, 30.0), atol=0.5)
    assert set(found[1].cells) == set(soft)
    # a patch really smaller than the smallest area is still dropped
    assert [c.sign for c in segment(mesh, z, min_area=60.0)] == [1]


def test_segment_summarises_a_patch_by_its_ellipse_of_moments():
    mesh = jf.rectangle(0.0, 0.0, 100.0, 60.0, 50, 30)
    c = mesh.centroids()
    u, v = c[:, 0] - 40.0, c[:, 1] - 25.0
    t = np.pi / 6
    inside = ((u * np.cos(t) + v * np.sin(t)) / 15.0) ** 2 + ((-u * np.sin(t) + v * np.cos(t)) / 6.0) ** 2 < 1
    z = np.where(inside, -0.8, 0.0)
    (cand,) = segment(mesh, z)
    assert cand.sign == -1 and cand.peak == 0.8
    assert np.allclose(cand.centroid, (40.0, 25.0), atol=0.5)
    assert np.allclose(cand.axes, (15.0, 6.0), rtol=0.08)
    assert abs(np.angle(np.exp(2j * (cand.angle - t)))) / 2 < 0.05
