"""The 3D diagnosis's null test: is the SOUND cup holder's model wrong beyond the noise and its
own discretisation (as the 2D diagnosis's null level includes its model's discretisation error,
:mod:`refine.diagnosis.discretisation`)?

The local model (:mod:`refine.solid.local`: the bottom slab alone, held by its outer face's ring
under the wall) is no null model: it leaves the wall out, which holds the floor's edge against
rotation, so it misses a sound cup holder's data by far more than the noise, noise-free data too.
The global model (the whole cup holder held by the fixture's points; no hole, the null
hypothesis) with a uniform modulus fitted (its mesh's stiffness, what the global refit's modulus
absorbs beside a hole) misses them by about the noise.

So the null test weighs the global model's misfit at the bottom's guide points, its modulus
fitted in closed form, against the noise and the model's discretisation error: the RMS change of
its (modulus-fitted) predictions on a mesh sqrt(2) coarser (Richardson's estimate for errors of
second order: the change itself). The rim's noise carried to the bottom through the wall is left
out (three rings of points averaged onto the rim, 8 mm away).
"""

from __future__ import annotations

import numpy as np
from jaxtyping import Bool, Float

from refine.bundle.io import Bundle
from refine.diagnosis.noise import NullTest, null_test
from refine.measures import Residuals
from refine.solid.local import HOLE_HEADROOM, Local, Whole

COARSER = float(np.sqrt(2.0))
"""The global model's coarser mesh for its discretisation error: ``h`` times this."""


def global_prediction(bundle: Bundle, local: Local, h: float | None = None) -> Float[np.ndarray, "frames n 3"]:
    """The global model without a hole (the whole cup holder held by the fixture's points and
    squeezed by the measured force: :meth:`refine.solid.local.Whole.of`, as the hole's global
    refit), at element size ``h`` (length unit; None: ``local.h``), predicting the local model's points
    (``local.obs``, in its order): ``(frames, n, 3)``. Raises the model's solve failure (naming
    where Newton stopped) where it cannot be solved: a null test on NaN would pass silently."""
    whole, _ = Whole.of(local, bundle.observations, h)
    held = whole.obs
    model, _ = whole.model(headroom=HOLE_HEADROOM)  # the hole's global meshes share its programs
    where = {int(i): k for k, i in enumerate(held.ids)}
    pred = np.asarray(model.predict(model.params()))[:, [where[int(i)] for i in local.obs.ids]]
    if not np.isfinite(pred).all():
        model.raise_solve_failure(model.params())
    return pred


def rms(d: Float[np.ndarray, "frames n 3"], points: Bool[np.ndarray, "n"]) -> float:
    """Root mean square (length unit) of ``d`` over every frame and component at ``points``."""
    return float(np.sqrt(np.nanmean(np.asarray(d)[:, points] ** 2)))


def scaled(measured, predicted, points, sigma: float) -> tuple[np.ndarray, float]:
    """``predicted`` ``(frames, n, 3)`` times the least-squares factor against ``measured`` at
    ``points`` (a uniform modulus fitted in closed form: displacements under a measured force scale
    about as 1/E, as :func:`refine.solid.start.best_start` takes them), and the modulus factor
    (the factor's inverse, x the experiment's E)."""
    at = Residuals.at(measured, points, sigma)
    v = at.weighted(np.asarray(predicted))
    m = at.weighted(np.nan_to_num(np.asarray(measured)))
    k = float(v @ m / max(v @ v, 1e-300))
    return k * np.asarray(predicted), 1.0 / k


def global_null(bundle: Bundle, local: Local, points: Bool[np.ndarray, "n"], sigma: float) -> tuple[NullTest, dict]:
    """The null test of the sound cup holder's global model (see the module) at ``points`` of
    ``local.obs`` (the guide points), noise ``sigma`` (length unit), and what it took: ``modulus``
    (the fitted factor), ``mesh`` (its discretisation error, length unit), ``coarse_modulus``.
    Costs a solve of the global model and one on the coarser mesh."""
    obs = local.obs
    g, E = scaled(obs.displacements, global_prediction(bundle, local), points, sigma)
    gc, Ec = scaled(obs.displacements, global_prediction(bundle, local, COARSER * local.h), points, sigma)
    mesh = rms(gc - g, points)
    at = Residuals.at(obs.displacements, points, sigma)
    diff = at.difference(g)
    null = null_test(diff, at.valid, sigma, mesh, np.zeros((0, *diff.shape)))
    return null, {"model": "global", "h": local.h, "modulus": E, "coarse_modulus": Ec, "mesh": mesh}
