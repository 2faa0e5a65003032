"""The measured strain map, gaps in the tracked points, the hole-naming rule and the search's
frames and mesh size: small problems (no finite-element solve), each drawn under a seed."""

import numpy as np
import pytest
from matplotlib.figure import Figure

import jaxfem as jf
from refine.bundle.experiment import PolygonDomain, RectangleDomain
from refine.bundle.observations import Observations
from refine.diagnosis.candidates import merged, missing_point_regions
from refine.diagnosis.fitted import Fitted
from refine.diagnosis.holes import named_hole
from refine.diagnosis.localize import Candidate
from refine.diagnosis.measured_strain import measured_strain
from refine.diagnosis.scale import at_frames, mesh_size, search_frames
from refine.diagnosis.shapes import RegionShape
from refine.diagnosis.strain_figures import strain_maps_figure


def _jittered_grid(rng, spacing=2.0, roi=(0.0, 0.0, 60.0, 40.0), jitter=0.15):
    x0, y0, x1, y1 = roi
    X, Y = np.meshgrid(np.arange(x0, x1 + 1e-9, spacing), np.arange(y0, y1 + 1e-9, spacing))
    pts = np.stack([X.ravel(), Y.ravel()], 1)
    inner = (pts[:, 0] > x0) & (pts[:, 0] < x1) & (pts[:, 1] > y0) & (pts[:, 1] < y1)
    pts[inner] += rng.uniform(-jitter, jitter, (inner.sum(), 2)) * spacing
    return pts


def test_measured_strain_of_a_homogeneous_deformation_is_exact():
    rng = np.random.default_rng(3)
    pts = _jittered_grid(rng)
    F = np.eye(2) + rng.uniform(-0.2, 0.2, (2, 2))
    u = np.stack([pts @ (F - np.eye(2)).T, pts @ (1.1 * F - np.eye(2)).T])  # two frames
    u[1, 7] = np.nan  # a point lost in the second frame
    tri, E = measured_strain(pts, u)
    assert E.shape == (2, len(tri), 2, 2)
    np.testing.assert_allclose(E[0], np.broadcast_to(0.5 * (F.T @ F - np.eye(2)), E[0].shape), atol=1e-12)
    lost = (tri == 7).any(axis=1)
    assert lost.any() and np.isnan(E[1][lost]).all() and np.isfinite(E[1][~lost]).all()


def test_triangles_across_a_gap_are_left_out():
    rng = np.random.default_rng(4)
    pts = _jittered_grid(rng)
    gap = np.hypot(pts[:, 0] - 30.0, pts[:, 1] - 20.0) < 6.0
    tri, _ = measured_strain(pts[~gap], np.zeros((int((~gap).sum()), 2)))
    centres = pts[~gap][tri].mean(axis=1)
    assert not (np.hypot(centres[:, 0] - 30.0, centres[:, 1] - 20.0) < 4.0).any()


@pytest.mark.parametrize("seed", [5, 6])
def test_a_gap_in_the_points_is_a_hole_candidate(seed):
    """A hole drawn at random (place, axes, angle) leaves no tracked point inside it, and a ring
    of lost points around it; the gap is found, centred within a spacing, its area within the
    ring's margin, and a few scattered lost points are no candidate."""
    rng = np.random.default_rng(seed)
    spacing = 2.0
    pts = _jittered_grid(rng, spacing)
    a, b = rng.uniform(4.0, 8.0, 2)
    hole = jf.Ellipse(rng.uniform(20, 40), rng.uniform(15, 25), a, b, rng.uniform(0, np.pi))
    near = np.linalg.norm(pts - hole.to_curve(pts), axis=1) < rng.uniform(0.3, 1.0) * spacing
    lost = rng.random(len(pts)) < 0.02  # single lost points elsewhere
    keep = ~(hole.contains(pts) | near | lost)
    domain = PolygonDomain(((0.0, 0.0), (60.0, 0.0), (60.0, 40.0), (0.0, 40.0)))
    found = missing_point_regions(pts[keep], domain)
    assert len(found) == 1, [c.centroid for c in found]
    c = found[0]
    assert c.sign == -1 and c.source == "missing-points"
    assert np.hypot(*(c.centroid - [hole.cx, hole.cy])) < spacing
    # the candidate is a start (a hole fit shrinks it until no point lies inside): its area is
    # the hole's grown by up to about a spacing all round
    area = np.pi * c.axes[0] * c.axes[1]
    assert np.pi * a * b * 0.8 < area < np.pi * (a + 1.5 * spacing) * (b + 1.5 * spacing)
    # a known hole in the domain is no candidate
    square = [(hole.cx - a - b, hole.cy - a - b), (hole.cx + a + b, hole.cy - a - b),
              (hole.cx + a + b, hole.cy + a + b), (hole.cx - a - b, hole.cy + a + b)]
    assert missing_point_regions(pts[keep], RectangleDomain(0.0, 0.0, 60.0, 40.0, holes=(square,))) == []


def test_one_place_seen_twice_is_one_candidate():
    def cand(x, sign, source):
        return Candidate(sign, np.arange(3), np.array([x, 10.0]), np.array([4.0, 3.0]), 0.0, 1.0, 1.0, source)

    out = merged([cand(10.0, -1, "missing-points")], [cand(11.0, -1, "field"), cand(11.0, 1, "field")],
                 [cand(30.0, 1, "strain")])
    assert [(c.source, c.sign) for c in out] == [("missing-points", -1), ("field", 1), ("strain", 1)]


class _Soft:
    """A fitted one-region hypothesis as the naming rule sees it."""

    law = "neo-hookean"
    remeshable = True

    def cause_of(self, shapes):
        return "softer-region"


def _fitted(ratio, z_std, centre=(30.0, 20.0)):
    shape = RegionShape(centre, (5.0, 3.0), 0.3, "ellipse", ratio)
    return Fitted(_Soft(), 6, 100.0, 50.0, 120.0, np.zeros((1, 1, 2)), None, {}, 0.02, (shape,),
                  z_std=np.array([z_std, 0.1, 0.1, 0.1, 0.1, 0.1]))


@pytest.mark.parametrize("ratio,z_std,points_inside,hole", [
    (0.004, 0.1, False, True),   # stiffness below the threshold, no point inside: a hole
    (0.2, 0.8, False, True),     # within two standard errors of zero: a hole
    (0.004, 0.1, True, False),   # material was tracked inside: a (very) soft region
    (0.2, 0.1, False, False),    # clearly stiffer than nothing: a soft region
])
def test_a_soft_region_of_no_stiffness_and_no_points_is_named_a_hole(ratio, z_std, points_inside, hole):
    pts = np.array([[0.0, 0.0], [60.0, 40.0]] + ([[31.0, 20.5]] if points_inside else []))
    f = named_hole(_fitted(ratio, z_std), pts, below=0.05)
    assert f.cause == ("hole" if hole else "softer-region")
    if hole:
        assert f.shapes[0].kind == "hole" and f.shapes[0].centre == (30.0, 20.0) and f.shapes[0].ratio == 0.0


def test_the_search_uses_the_frames_of_most_motion_and_a_mesh_from_the_domain():
    rng = np.random.default_rng(8)
    n, frames = 50, 11
    scale = rng.permutation(np.linspace(0.1, 1.0, frames))  # motion not in frame order
    disp = scale[:, None, None] * rng.normal(0, 1, (1, n, 2))
    obs = Observations(np.arange(n), rng.uniform(0, 10, (n, 2)), np.array(["guide"] * n), disp)
    top = int(np.argmax(scale))
    assert search_frames(obs, 1) == (top,)
    two = search_frames(obs, 2)
    assert top in two and abs(scale[[f for f in two if f != top][0]] - 0.5 * scale[top]) < 0.05
    assert search_frames(obs, 0) == tuple(range(frames))
    sub = at_frames(obs, two)
    np.testing.assert_array_equal(sub.displacements, obs.displacements[list(two)])
    # half the spacing for sparse points; the cell count capped for dense ones
    domain = RectangleDomain(0.0, 0.0, 100.0, 60.0)
    assert mesh_size(domain, 10.0, 3000) == 5.0
    h = mesh_size(domain, 1.0, 3000)
    assert abs(2 * 6000.0 / h**2 - 3000) < 1


def test_the_strain_figure_shows_measured_and_model_maps_side_by_side():
    rng = np.random.default_rng(9)
    pts = _jittered_grid(rng)
    u = 0.01 * pts + rng.normal(0, 1e-3, pts.shape)
    fig = strain_maps_figure(pts, {"measured": u, "initial model": 0.01 * pts, "refined model": 0.011 * pts},
                             "test", outlines=[[[10, 10], [20, 10], [20, 20]]])
    assert isinstance(fig, Figure)
    assert [ax.get_title() for ax in fig.axes[:3]] == ["measured", "initial model", "refined model"]
