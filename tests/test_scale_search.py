"""The diagnosis at scale: the drive's covariance needs ``J^T dr/dB`` (k rows of the drive
Jacobian), pulled back by one adjoint solve per unknown and frame
(:func:`refine.model.drive.boundary_vjp`) instead of a tangent solve per boundary value and frame
where the boundary values are many (the forward way where they are few). Both against the whole drive Jacobian on a small sheet, its motion, the cotangents and the
residuals' Jacobian drawn under a seed, a point lost in one frame."""

import numpy as np
import pytest

from refine.bundle.experiment import Experiment, RectangleDomain
from refine.bundle.observations import Observations
from refine.diagnosis.uncertainty import _pulled_shared
from refine.measures import Residuals
from refine.model.drive import boundary_vjp
from refine.model.measured import MeasuredModel


def _sheet(rng):
    """A 40 x 30 mm sheet tracked on a 5 mm grid (edge points drive it), stretched and sheared
    over two frames."""
    X, Y = np.meshgrid(np.arange(0.0, 40.1, 5.0), np.arange(0.0, 30.1, 5.0))
    pts = np.stack([X.ravel(), Y.ravel()], 1)
    edge = (pts[:, 0] == 0) | (pts[:, 0] == 40) | (pts[:, 1] == 0) | (pts[:, 1] == 30)
    a = rng.uniform(0.005, 0.02, 3)
    u = np.stack([a[0] * pts[:, 0] + a[2] * pts[:, 1], a[1] * pts[:, 1]], 1)
    disp = np.stack([0.5 * u, u]) + rng.normal(0, 0.002, (2, *pts.shape))
    disp[1, np.flatnonzero(~edge)[4]] = np.nan  # a guide point lost in the second frame
    ex = Experiment("pulled", "plane-stress", RectangleDomain(0.0, 0.0, 40.0, 30.0), "neo-hookean", 1.0, 0.3,
                    noise_std=0.002)
    return ex, Observations(np.arange(len(pts)), pts, np.where(edge, "boundary", "guide"), disp)


@pytest.mark.slow  # 42 s at load 10 (compiles Newton, tangents, adjoint and both point maps)
def test_drive_pullback_equals_the_drive_jacobians_rows():
    rng = np.random.default_rng(23)
    ex, obs = _sheet(rng)
    model = MeasuredModel(ex, obs, h=6.0)
    theta = model.params()
    whole = model.boundary_jacobian(theta)  # (frames, points, dim, frames, m)
    C = rng.normal(size=(3,) + obs.displacements.shape)
    want = np.einsum("cfpd,fpdgm->cgm", C, whole)
    # the reverse way (one adjoint solve per cotangent and frame: a bundle with many boundary
    # values), and the forward way this small sheet takes by default (the Jacobian contracted)
    np.testing.assert_allclose(boundary_vjp(model, theta, C, forward_batches=0), want,
                               atol=1e-9 * np.abs(whole).max() * np.abs(C).max())
    np.testing.assert_allclose(model.boundary_vjp(theta, C), want, atol=1e-9 * np.abs(whole).max() * np.abs(C).max())
    res = Residuals.at(obs.displacements, obs.mask("guide"), sigma=0.002)
    J = rng.normal(size=(res.n, 3))
    want = J.T @ res.jacobian(whole.reshape(whole.shape[:3] + (-1,)))
    np.testing.assert_allclose(_pulled_shared(model, res, theta, J), want, atol=1e-9 * np.abs(want).max())
