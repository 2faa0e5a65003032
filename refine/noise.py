"""How large a misfit the initial model may show when it is right: measurement noise (given or
estimated from the data), its propagation from the driving boundary points, and the model's own
discretisation error.

A homogeneous sample must yield no finding: the decision compares the baseline misfit with this
null level, never with zero.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np
from scipy import stats
from scipy.spatial import cKDTree

from .observations import Observations


def estimate_noise(obs: Observations, k: int = 12) -> float:
    """Standard deviation of the displacement noise estimated from the data alone.

    Each point's displacement is predicted from its ``k`` nearest neighbours by a local quadratic
    fit; the prediction residual has variance sigma^2 (1 + leverage). A median makes the estimate
    robust to the few places where the field is not locally smooth (an inclusion's edge).
    """
    X = obs.reference
    _, nb = cKDTree(X).query(X, k=k + 1)
    ratios = []
    for i in range(len(X)):
        j = nb[i, 1:]
        d = X[j] - X[i]
        s = np.abs(d).max() or 1.0
        d = d / s
        A = np.column_stack([np.ones(len(j)), d, d[:, 0] ** 2, d[:, 0] * d[:, 1], d[:, 1] ** 2])
        pinv = np.linalg.pinv(A)
        a0 = pinv[0]  # weights giving the fitted value at the point itself
        lev = float(a0 @ a0)
        for f in range(obs.n_frames):
            U = obs.displacements[f, j]
            ui = obs.displacements[f, i]
            if not (np.isfinite(U).all() and np.isfinite(ui).all()):
                continue
            e = ui - a0 @ U
            ratios.extend((e**2 / (1.0 + lev)).tolist())
    if not ratios:
        return 0.0
    return float(np.sqrt(np.median(ratios) / stats.chi2.ppf(0.5, 1)))


@dataclass(frozen=True)
class NullTest:
    """The baseline misfit against its null distribution.

    Attributes:
        statistic: whitened squared misfit r^T C^-1 r over the matched points and frames.
        dof: number of residuals.
        p_value: probability of a misfit at least this large if the model were right.
        sigma: measurement noise used; sigma_model: the discretisation floor; propagation: mean
            variance factor added by noise on the driving boundary points.
    """

    statistic: float
    dof: int
    p_value: float
    sigma: float
    sigma_model: float
    propagation: float

    @property
    def ratio(self) -> float:
        """Misfit relative to its expectation (about 1 when the model explains the data)."""
        return self.statistic / max(self.dof, 1)


def boundary_sensitivity(model, theta, frame: int, points: np.ndarray):
    """Jacobian of the predicted displacements at ``points`` w.r.t. the measured boundary
    displacements of one frame, ``(n_points * dim, n_boundary * dim)`` (implicit tangent solves)."""
    b0 = jnp.asarray(model.boundary_displacements(frame))
    idx = np.flatnonzero(points)

    def pred(b):
        th = {**theta, "u_D": model.prescribed(frame, b)}
        return model.probe(model.solver.displacement(th))[idx].reshape(-1)

    return np.asarray(jax.jacfwd(pred)(b0))


def null_test(residuals: np.ndarray, valid: np.ndarray, sigma: float, sigma_model: float, J: np.ndarray) -> NullTest:
    """Test whether ``residuals (frames, n, dim)`` are explained by noise and model error.

    The covariance of one frame's residuals under the null is
    ``sigma^2 (I + J J^T) + sigma_model^2 I``, with ``J`` the boundary sensitivity; frames are
    independent.
    """
    n, dim = residuals.shape[1], residuals.shape[2]
    stat, dof = 0.0, 0
    base = sigma**2 * (np.eye(n * dim) + J @ J.T) + sigma_model**2 * np.eye(n * dim)
    for f in range(residuals.shape[0]):
        keep = np.repeat(valid[f], dim)
        r = residuals[f].reshape(-1)[keep]
        C = base[np.ix_(keep, keep)]
        L = np.linalg.cholesky(C + 1e-300 * np.eye(len(C)))
        w = np.linalg.solve(L, r)
        stat += float(w @ w)
        dof += len(r)
    prop = float(np.mean(np.sum(J * J, axis=1))) if J.size else 0.0
    return NullTest(stat, dof, float(stats.chi2.sf(stat, dof)), sigma, sigma_model, prop)
