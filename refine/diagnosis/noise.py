"""How large a misfit the initial model may show when it is right: measurement noise (given or
estimated from the data), its propagation from the driving boundary points, and the model's own
discretisation error.

A homogeneous sample must yield no finding: the decision compares the baseline misfit with this
null level, never with zero.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from jaxtyping import Bool, Float
from scipy import stats
from scipy.spatial import cKDTree

from refine.bundle.observations import Observations


def estimate_noise(obs: Observations, k: int = 12) -> float:
    """Standard deviation of the displacement noise estimated from the data alone.

    Each point's displacement is predicted from its ``k`` nearest neighbours by a local quadratic
    fit; the prediction residual has variance sigma^2 (1 + leverage). A median makes the estimate
    robust to the few places where the field is not locally smooth (an inclusion's edge).
    """
    return noise_at(obs, np.ones(obs.n_points, bool), k)


def noise_at(obs: Observations, where: np.ndarray, k: int = 12) -> float:
    """:func:`estimate_noise` from the points ``where`` ``(n_points,)`` bool only (their
    neighbours taken among all points): the noise of one part of the data, such as a band along
    a free edge where the correlation degrades. 0 where no residual is available."""
    X = obs.reference
    _, nb = cKDTree(X).query(X, k=k + 1)
    ratios = []
    for i in np.flatnonzero(where):
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


def propagated_noise(model, theta, sigma: float, points: Bool[np.ndarray, "n_points"], samples: int = 12,
                     seed: int = 0) -> Float[np.ndarray, "samples frames m dim"]:
    """How noise on the driving boundary points moves the predictions at ``points``: predictions
    for ``samples`` noisy copies of the measured boundary motion (Monte Carlo through the
    nonlinear model, reusing its compiled solve). Returns the deviations
    ``(samples, frames, n_points, dim)`` from the prediction with the measured boundary."""
    rng = np.random.default_rng(seed)
    B = model.measured_boundary()
    ref = np.asarray(model.predict(theta))[:, points]
    out = []
    for _ in range(samples):
        Bn = B + sigma * rng.standard_normal(B.shape)
        out.append(np.asarray(model.predict(theta, boundary=Bn))[:, points] - ref)
    return np.stack(out)


def null_test(residuals: Float[np.ndarray, "frames m dim"], valid: Bool[np.ndarray, "frames m"], sigma: float,
              sigma_model: float, propagated: Float[np.ndarray, "samples frames m dim"]) -> NullTest:
    """Test whether ``residuals (frames, n, dim)`` are explained by noise and model error.

    The covariance of the residuals under the null is ``(sigma^2 + sigma_model^2) I + V V^T``,
    with ``V`` the sampled propagation of boundary noise (``propagated``, samples first): a
    diagonal plus a low-rank, smooth part, solved by the Woodbury identity.
    """
    keep = np.repeat(valid.reshape(-1), residuals.shape[-1])
    r = residuals.reshape(-1)[keep]
    K = len(propagated)
    V = propagated.reshape(K, -1)[:, keep].T / np.sqrt(max(K - 1, 1)) if K else np.zeros((len(r), 0))  # (n, K)
    d = sigma**2 + sigma_model**2
    if d <= 0:
        d = 1e-30
    # r^T (d I + V V^T)^-1 r = (r.r - (V^T r)^T (d I_K + V^T V)^-1 (V^T r)) / d
    Vr = V.T @ r
    small = d * np.eye(K) + V.T @ V
    stat = float((r @ r - Vr @ np.linalg.solve(small, Vr)) / d)
    prop = float(np.mean(np.sum(V * V, axis=1)) / d) if K else 0.0
    return NullTest(stat, len(r), float(stats.chi2.sf(stat, len(r))), sigma, sigma_model, prop)
