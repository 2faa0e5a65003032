"""What a fit minimises: a parametrised model's noise-weighted misfit on measured points.

An :class:`Objective` joins a :class:`~refine.model.MeasuredModel`, a parametrisation and a set
of measured points (the guide set, by default): its residuals are the noise-weighted differences
between predicted and measured displacements over all frames (lost points removed), and its
value is half their squared norm plus the parametrisation's regulariser. :class:`Compiled` is the
same model with its prediction and Jacobian compiled once for all points, for fits on several
point sets. The optimisers that take them are in :mod:`refine.optimize`.
"""

from __future__ import annotations

from functools import cached_property

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Float

from refine.measures import Residuals, displacement_error
from refine.model.measured import MeasuredModel, frame_traction
from refine.model.shared import Shared


class Objective:
    """Noise-weighted misfit of a parametrised model on one role's points.

    Args:
        model: the measured model.
        param: a parametrisation (see :mod:`refine.model.parametrize`).
        theta: base parameters (default: the model's initial ones).
        role: which points are matched (``"guide"``; a subset mask may be given as ``points``).
        points: optional boolean mask over all points overriding ``role``.
        noise_std: weight of the residuals (default: the bundle's noise, or 1).

    Its compiled pieces (:attr:`residuals_and_jacobian`, :attr:`value_and_grad`) are traced on
    first use and run on programs shared with every objective that traces to the same program
    (:class:`~refine.model.shared.Shared`: the arrays they close over are arguments), so later
    fits of this objective, and of another one of the same shapes, compile nothing.
    """

    def __init__(self, model: MeasuredModel, param, theta=None, role: str = "guide", points=None,
                 noise_std: float | None = None):
        self.model, self.param = model, param
        self.theta = model.params() if theta is None else theta
        obs = model.obs
        sigma = noise_std if noise_std is not None else (model.experiment.noise_std or 0.0)
        sigma = float(sigma) if sigma and sigma > 0 else 1.0
        self.at_points = Residuals.at(obs.displacements, obs.mask(role) if points is None else points, sigma)
        self.n_forward = 0
        self.n_gradient = 0

    @property
    def points(self) -> np.ndarray:
        """``(n_points,)`` bool: the matched points."""
        return self.at_points.points

    @property
    def valid(self) -> np.ndarray:
        """``(frames, m)`` bool: where the matched points were tracked."""
        return self.at_points.valid

    @property
    def measured(self) -> np.ndarray:
        """``(frames, m, dim)`` measured displacements at the matched points (0 where lost)."""
        return self.at_points.measured

    @property
    def sigma(self) -> float:
        return self.at_points.sigma

    @property
    def n_residuals(self) -> int:
        return self.at_points.n

    def predict(self, z):
        """Predicted displacements of all points ``(frames, n_points, dim)``."""
        return self.model.predict(self.param.apply(self.theta, z))

    def residuals(self, z):
        """``(n_residuals,)`` noise-weighted residuals over matched, tracked points."""
        return self.residuals_of(self.predict(z))

    def residuals_of(self, predicted):
        """The residuals of predicted displacements of all points ``(frames, n_points, dim)``
        (for a caller that solved already)."""
        return self.at_points(predicted)

    def weighted(self, values):
        """Point values ``(frames, n_points, dim)`` noise-weighted at the matched, tracked points,
        ``(n_residuals,)``: the residuals' linear part (e.g. a series of predicted displacements)."""
        return self.at_points.weighted(values)

    def value(self, z):
        r = self.residuals(z)
        return 0.5 * jnp.sum(r * r) + self.param.regularization(z)

    @cached_property
    def residuals_and_jacobian(self):
        """``z -> (J, r)``, compiled: the Jacobian ``(n_residuals, k)`` of the residuals (forward
        mode, one tangent solve per unknown and frame at the converged state) and the residuals
        ``(n_residuals,)``, from one solve."""
        return Shared(jax.jacfwd(lambda z: (self.residuals(z),) * 2, has_aux=True))

    @cached_property
    def value_and_grad(self):
        """``z -> (value, gradient)`` (the gradient by one adjoint solve per frame): on the
        solver's shared programs (:mod:`jaxfem.program`) where the model solves its frames as
        :class:`~refine.model.MeasuredModel` does and the misfit is this class's, else one program
        (:class:`~refine.model.shared.Shared`)."""
        if self.model.shares_programs and type(self).value is Objective.value \
                and type(self).residuals is Objective.residuals and self.model.frame_tractions(self.theta["X"]) is None:
            return self._shared_value_and_grad
        return Shared(jax.value_and_grad(self.value))

    @cached_property
    def _pieces(self):
        """The compiled pieces of :meth:`_shared_value_and_grad` that belong to this objective
        (small: no solve in them): the parametrisation with its pullback (compiled per objective;
        the pullback runs eagerly), and the misfit of the
        nodal displacements with its gradient in them, in the reference nodes and in ``z``
        (:class:`~refine.model.shared.Shared`)."""
        def misfit(U, X, z):
            r = self.residuals_of(self.model.at_points(U, {"X": X}))
            return 0.5 * jnp.sum(r * r) + self.param.regularization(z)

        apply = jax.jit(lambda z: jax.vjp(lambda zz: self.param.apply(self.theta, zz), z))
        return apply, Shared(jax.value_and_grad(misfit, argnums=(0, 1, 2)))

    def _shared_value_and_grad(self, z):
        apply, misfit = self._pieces
        z = np.asarray(z, float)
        theta, pullback = apply(z)
        model, B = self.model, self.model.measured_boundary()
        start, U, states = model.frame_starts(theta), [], []
        for f in range(model.obs.n_frames):
            u_D = model.drives[f].matrix @ B[f]
            u, state = model.solver.solve_for_adjoint({**theta, "u_D": u_D}, start=start)
            start = (np.asarray(u).reshape(-1), {**start[1], "u_D": u_D})
            U.append(u)
            states.append(state)
        value, (gU, gX, gz) = misfit(np.stack(U), theta["X"], z)
        gU = np.asarray(gU)  # (host numpy from here: an eager operation compiles a program per shape)
        g_theta = {k: np.zeros(np.shape(v)) for k, v in theta.items()}
        g_theta["X"] = np.asarray(gX, float).copy()
        for f, state in enumerate(states):
            for k, v in model.solver.adjoint(state, gU[f]).items():
                g_theta[k] = g_theta[k] + np.asarray(v)
        g_theta["u_D"] = np.zeros(np.shape(theta["u_D"]))  # the drive does not depend on z
        return value, pullback(jax.tree.map(jnp.asarray, g_theta))[0] + gz

    def paper_error(self, z) -> float:
        """The paper's eq. (1): sum of distances between predicted and measured positions."""
        pred = np.asarray(self.predict(z))[:, self.points]
        meas = np.where(self.valid[..., None], np.asarray(self.measured), np.nan)
        return displacement_error(pred, meas).value


class Compiled:
    """A model and parametrisation whose prediction and Jacobian are computed together, for all
    points: fits on different point sets (fit, held-out, all guide points) and scoring then
    reuse the same evaluation. ``evaluate(z) -> (prediction, jacobian)`` with shapes
    ``(frames, points, dim)`` and ``(frames, points, dim, k)`` (forward mode: one tangent solve
    per unknown and frame at the converged state, next to the forward solve); ``predict`` and
    ``jacobian`` are its halves, and ``predict`` alone solves no tangents (they are solved from
    the kept converged states when ``jacobian`` asks for the same ``z``: a fit's rejected steps
    and its last one cost the forward solves only).

    The solves run on the solver's shared programs (:mod:`jaxfem.program`: Newton, then the
    tangents along the k parameter directions), which every model of about the same mesh size,
    element and law reuses: a hypothesis remeshed at its fitted shapes compiles no solve again.
    The parametrisation and its Jacobian (``theta(z)``, ``dtheta/dz``) run on a program shared by
    every instance that traces to the same one (:class:`~refine.model.shared.Shared`: the same
    shapes, whatever the masks, morph or base parameters); the points' interpolation and its
    derivative on a program shared by models of about the same size
    (:mod:`refine.model.interpolation`)."""

    def __init__(self, model: MeasuredModel, param, theta=None):
        self.model, self.param = model, param
        self.theta = model.params() if theta is None else theta

        def apply(z):
            th = param.apply(self.theta, z)
            return th, jax.jacfwd(param.apply, argnums=1)(self.theta, z)

        self._apply = Shared(apply)
        self._tractions = None
        if model.frame_tractions(self.theta["X"]) is not None:  # each frame's load follows the geometry
            def tractions(z):
                return model.frame_tractions(param.apply(self.theta, z)["X"])

            self._tractions = Shared(lambda z: (tractions(z), jax.jacfwd(tractions)(z)))
        if not model.shares_programs:  # a model that solves its frames its own way: one program per model
            def f(z):
                y = model.predict(param.apply(self.theta, z))
                return y, y

            self._evaluate = Shared(jax.jacfwd(f, has_aux=True))
        self._last = None

    def theta_at(self, z) -> dict:
        """The solver's parameters at ``z`` (``param.apply(theta, z)``), from the program the
        solves take them from (compiled: a fused program's last bits, not eager operations'):
        the last solve's where it was at ``z``."""
        z = np.asarray(z, float)
        last = self._last
        if last is not None and "theta" in last and np.array_equal(last["z"], z):
            return last["theta"]
        return self._apply(z)[0]

    def _solve(self, z) -> dict:
        """The equilibrium at ``z``, frame after frame from the one before: ``{"z", "U": nodal
        displacements (frames, n_nodes, dim), "states": each frame's converged state, "dirs":
        each frame's parameter directions (k leading), "theta", "dX" (k, n_nodes, dim)}``; the
        tangents along the directions are left for :meth:`_derivatives` (a fit asks for the
        Jacobian at its accepted steps only, not at a rejected step or the last one)."""
        model = self.model
        theta, T = self._apply(np.asarray(z, float))
        k = int(np.size(z))
        dirs = {key: np.moveaxis(np.asarray(v), -1, 0) for key, v in T.items()}
        dirs["u_D"] = np.zeros((k, len(model.problem.fixed)))  # the drive does not depend on z
        B, start = model.measured_boundary(), model.frame_starts(theta)
        # on the host: each frame's slice of device arrays compiled a small program per facet count
        T, dT = (None, None) if self._tractions is None else jax.device_get(self._tractions(np.asarray(z, float)))
        U, states, frame_dirs = [], [], []
        for f in range(model.obs.n_frames):
            loads = {"u_D": model.drives[f].matrix @ B[f], **frame_traction(T, f)}
            frame_dirs.append(dirs if T is None else {**dirs, "traction": np.moveaxis(np.asarray(dT[f]), -1, 0)})
            u, state = model.solver.solve_for_adjoint({**theta, **loads}, start=start)
            start = (np.asarray(u).reshape(-1), {**start[1], **loads})
            U.append(u)
            states.append(state)
        return {"z": np.asarray(z, float).copy(), "U": np.stack(U), "states": states, "dirs": frame_dirs,
                "theta": theta, "dX": np.asarray(dirs["X"])}

    def _derivatives(self, s: dict):
        """``(prediction, Jacobian (frames, n_points, dim, k))`` of a :meth:`_solve` result: the
        tangents at its converged states, then the points' interpolation and its derivatives."""
        dU = np.stack([self.model.solver.tangents_at(st, d) for st, d in zip(s["states"], s["dirs"])], 1)
        pred, J = self.model.at_points_and_derivatives(s["U"], dU, s["theta"]["X"], s["dX"])
        return pred, np.moveaxis(J, 0, -1)

    def _prediction(self, s: dict):
        """The prediction of a :meth:`_solve` result alone: the program of :meth:`_derivatives`
        along a zero direction (the same figures)."""
        U, X = s["U"], s["theta"]["X"]
        return self.model.at_points_and_derivatives(U, np.zeros((1,) + U.shape), X, np.zeros((1,) + np.shape(X)))[0]

    def _at(self, z) -> dict:
        """The evaluation at ``z``, kept until another ``z`` is evaluated."""
        z = np.asarray(z, float)
        if self._last is None or not np.array_equal(self._last["z"], z):
            if self.model.shares_programs:
                self._last = self._solve(z)
            else:
                J, pred = self._evaluate(jnp.asarray(z))
                self._last = {"z": z.copy(), "pred": np.asarray(pred), "J": np.asarray(J)}
        return self._last

    def evaluate(self, z) -> tuple[Float[np.ndarray, "frames n_points dim"],
                                   Float[np.ndarray, "frames n_points dim k"]]:
        J = self.jacobian(z)
        return self.predict(z), J

    def predict(self, z) -> Float[np.ndarray, "frames n_points dim"]:
        s = self._at(z)
        if "pred" not in s:
            s["pred"] = self._prediction(s)
        return s["pred"]

    def jacobian(self, z) -> Float[np.ndarray, "frames n_points dim k"]:
        s = self._at(z)
        if "J" not in s:
            pred, s["J"] = self._derivatives(s)
            s.setdefault("pred", pred)  # (the same figures as a prediction made alone)
            del s["states"]  # the tangent matrices are not needed again
        return s["J"]
