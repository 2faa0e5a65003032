"""The measured strain of tracked points: exact for an affine motion, NaN where a point was lost,
no triangle across a hole."""

import numpy as np
import pytest

from refine.diagnosis.measured_strain import equivalent, measured_strain


def test_an_affine_motion_gives_its_strain_in_every_triangle():
    rng = np.random.default_rng(5)
    points = rng.uniform(0, 50, (80, 2))
    F = np.eye(2) + rng.normal(0, 0.1, (2, 2))  # drawn: any affine map
    u = np.stack([points @ (s * (F - np.eye(2))).T + rng.normal(0, 1, 2) for s in (0.5, 1.0)])
    tri, E = measured_strain(points, u)
    assert E.shape == (2, len(tri), 2, 2) and len(tri) > 80
    for s, Ef in zip((0.5, 1.0), E):
        Fs = np.eye(2) + s * (F - np.eye(2))
        np.testing.assert_allclose(Ef, np.broadcast_to(0.5 * (Fs.T @ Fs - np.eye(2)), Ef.shape), atol=1e-10)
    a, b, c = (points[tri[:, k]] for k in range(3))
    assert ((b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0] > 0).all()  # counter-clockwise
    # one frame at a time gives the same; a lost point makes its triangles NaN, only those
    lost = u[1].copy()
    lost[7] = np.nan
    _, E1 = measured_strain(points, lost)
    touched = (tri == 7).any(axis=1)
    assert np.isnan(E1[touched]).all() and np.allclose(E1[~touched], E[1][~touched])
    assert np.isfinite(equivalent(E1[~touched])).all()


def test_no_triangle_spans_a_hole():
    x, y = np.meshgrid(np.arange(0.0, 61.0, 5.0), np.arange(0.0, 41.0, 5.0))
    points = np.stack([x.ravel(), y.ravel()], 1)
    keep = np.hypot(points[:, 0] - 30, points[:, 1] - 20) > 12.0  # a hole of radius 12 (2.4 spacings)
    points = points[keep]
    tri, E = measured_strain(points, np.zeros_like(points))
    centres = points[tri].mean(axis=1)
    assert (np.hypot(centres[:, 0] - 30, centres[:, 1] - 20) > 8.0).all()
    assert np.allclose(E, 0.0)
    with pytest.raises(ValueError, match="like the points"):
        measured_strain(points, np.zeros((3, 2)))


def test_equivalent_strain_of_pure_shear():
    g = 0.01
    E = np.array([[0.0, g], [g, 0.0]])
    assert equivalent(E) == pytest.approx(np.sqrt(2.0 / 3.0 * 2 * g**2))
