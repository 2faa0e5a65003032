"""The diagnosis's initial model on every frame from the search model's compiled solve
(:func:`refine.diagnosis.scale.every_frame`): the same predictions as the model of every frame,
and not used where a lost boundary point drives a frame differently. A small sheet (a coarse
mesh), its motion drawn under a seed."""

import numpy as np

from refine.bundle.experiment import Experiment, RectangleDomain
from refine.bundle.observations import Observations
from refine.diagnosis.scale import at_frames, drives_alike, every_frame, search_frames
from refine.model.measured import MeasuredModel


def _pulled_sheet(rng, frames: int):
    """A 40 x 30 mm sheet tracked on a 5 mm grid (edge points drive it), pulled to the right by
    a random stretch, shear and bend per frame (up to 2 %)."""
    X, Y = np.meshgrid(np.arange(0.0, 40.1, 5.0), np.arange(0.0, 30.1, 5.0))
    pts = np.stack([X.ravel(), Y.ravel()], 1)
    edge = (pts[:, 0] == 0) | (pts[:, 0] == 40) | (pts[:, 1] == 0) | (pts[:, 1] == 30)
    roles = np.where(edge, "boundary", "guide")
    scale = np.sort(rng.uniform(0.1, 1.0, frames))
    a = rng.uniform(0.005, 0.02, 3)
    u = np.stack([a[0] * pts[:, 0] + a[1] * pts[:, 1], a[2] * pts[:, 0] ** 2 / 40.0], 1)
    disp = scale[:, None, None] * u[None] + rng.normal(0, 0.002, (frames, *pts.shape))
    ex = Experiment("pulled", "plane-stress", RectangleDomain(0.0, 0.0, 40.0, 30.0), "neo-hookean", 1.0, 0.3,
                    noise_std=0.002)
    return ex, Observations(np.arange(len(pts)), pts, roles, disp)


def test_every_frame_from_the_search_model_is_the_model_of_every_frame():
    ex, obs = _pulled_sheet(np.random.default_rng(31), 5)  # 5 frames: chunks of 2, the last one padded
    full = MeasuredModel(ex, obs, h=5.0)
    search = MeasuredModel(ex, at_frames(obs, search_frames(obs, 2)), mesh=full.mesh, h=full.h)
    assert drives_alike(search, full)
    want = np.asarray(full.predict(full.params()))
    got = every_frame(search, full, search.params())
    assert got.shape == want.shape == obs.displacements.shape
    np.testing.assert_allclose(got, want, atol=1e-9 * np.abs(want).max())
    # a boundary point lost in one frame drives that frame differently: no shortcut
    disp = obs.displacements.copy()
    disp[1, np.flatnonzero(obs.roles == "boundary")[3]] = np.nan
    lost = Observations(obs.ids, obs.reference, obs.roles, disp, obs.forces)
    assert not drives_alike(search, MeasuredModel(ex, lost, mesh=full.mesh, h=full.h))
