"""The z-buffer renderer of solids (refine.demo_data): depth, visibility and the per-pixel truth against
closed forms, through both cameras."""

import numpy as np
import pytest

import jaxfem as jf
import tracking
from examples.synthetic.rasterise import rasterise
from examples.synthetic.solid_render import SurfaceGrid, render_solid, surface_distance


def turned_block():
    """A 10 x 8 x 2 mm block (tet10: its facets are split at mid-edge nodes), turned 0.35 rad about
    x, so its bottom face is a tilted plane; returns the mesh and the turn."""
    mesh = jf.box(-5.0, -4.0, 0.0, 5.0, 4.0, 2.0, 3, 3, 1, "tet10")
    c, s = np.cos(0.35), np.sin(0.35)
    R = np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    return mesh, R


@pytest.mark.parametrize("model", ["orthographic", "perspective"])
def test_depth_and_truth_of_a_tilted_face_are_exact(model):
    mesh, R = turned_block()
    X = mesh.nodes
    u = X @ R.T - X                                         # the turn, as a displacement
    if model == "orthographic":
        camera = tracking.Camera("orthographic", scale=0.1, cx=60.0, cy=50.0, translation=[0.0, 0.0, -40.0])
    else:
        camera = tracking.Camera("perspective", fx=400.0, fy=400.0, cx=60.0, cy=50.0, translation=[0.0, 0.0, -40.0])
    view = render_solid(X, mesh.boundary_facets(), u, camera, (100, 120), depth_noise=0.0, noise_sigma=0.0)
    seen = np.isfinite(view.range)
    assert 0.2 < seen.mean() < 1.0                         # the block, with background around it
    # the camera below sees the bottom face (z = 0) and, the block being turned, one side face (y = 4
    # or -4, whichever faces it; x's sides are seen edge on): nothing inside the block
    M = view.material[seen]
    bottom = np.abs(M[:, 2]) < 1e-9
    side = np.abs(np.abs(M[:, 1]) - 4.0) < 1e-9
    assert np.all(bottom | side) and 0.5 < bottom.mean() < 0.99
    assert len(np.unique(np.sign(M[side, 1]))) == 1
    # the bottom face: the plane through R (0, 0, 0) with normal R e_z
    normal = R[:, 2]
    seen[seen] = bottom
    rows, cols = np.nonzero(seen)
    uv = np.stack([cols, rows], 1).astype(float)
    # each pixel's ray meets the plane at a depth in closed form
    if model == "orthographic":
        xy = (uv - [60.0, 50.0]) * 0.1
        depth = 40.0 - (normal[0] * xy[:, 0] + normal[1] * xy[:, 1]) / normal[2]
    else:
        ray = np.c_[(uv - [60.0, 50.0]) / 400.0, np.ones(len(uv))]
        depth = 40.0 * normal[2] / (ray @ normal)
    np.testing.assert_allclose(view.range[seen], depth, atol=1e-9)
    np.testing.assert_allclose(view.position[seen], camera.to_world(uv, depth), atol=1e-9)
    # the material point of each pixel is the bottom face's point that the turn carries there
    np.testing.assert_allclose(view.material[seen] @ R.T, view.position[seen], atol=1e-9)
    np.testing.assert_allclose(view.material[seen][:, 2], 0.0, atol=1e-9)
    assert np.median(view.image[np.isnan(view.range)]) < 20 and np.median(view.image[seen]) > 100


def test_grid_ink_and_z_buffer_order():
    grid = SurfaceGrid(pitch=1.0, line_width=0.2, edge=0.02)
    X = np.array([[0.0, 0.37, 5.0], [0.5, 0.5, 0.0], [0.1, 2.5, 1.0]])
    np.testing.assert_allclose(grid.ink(X), [1.0, 0.0, 0.5], atol=1e-6)
    # two triangles over the same pixels: the nearer wins wherever both are
    uv = np.array([[[0.0, 0.0], [20.0, 0.0], [0.0, 20.0]], [[0.0, 0.0], [20.0, 0.0], [20.0, 20.0]]])
    depth = np.array([[5.0, 5.0, 5.0], [3.0, 3.0, 3.0]])
    r = rasterise(uv, depth, (21, 21))
    both = (np.arange(21)[None, :] >= np.arange(21)[:, None]) & (np.add.outer(np.arange(21), np.arange(21)) <= 20)
    assert np.all(r.triangle[both] == 1) and np.allclose(r.depth[both], 3.0)
    assert np.all(r.triangle[np.add.outer(np.arange(21), np.arange(21)) > 20][:5] >= 0)


def test_surface_distance_is_exact_on_a_block():
    mesh = jf.box(0.0, 0.0, 0.0, 2.0, 2.0, 2.0, 2, 2, 2, "tet4")
    pts = np.array([[1.0, 1.0, 2.3], [1.0, 1.0, -0.1], [2.5, 2.5, 1.0], [1.2, 0.7, 2.0]])
    np.testing.assert_allclose(surface_distance(pts, mesh.nodes, mesh.boundary_facets()),
                               [0.3, 0.1, np.hypot(0.5, 0.5), 0.0], atol=1e-12)
