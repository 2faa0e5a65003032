"""The model of an object seen without correspondences: a mesh of the bundle's domain, held at
its clamped sides and moved at its gripped sides by an unknown rigid motion per frame; every other
boundary point is free. The grips' motion is found from the clouds together with the model's
parameters (:mod:`refine.correspond.fit`); the free outline and the interior follow from the
equilibrium, so every node has a position in every frame: the dense correspondences.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

import jaxfem as jf

from refine.bundle.experiment import Experiment, RectangleDomain
from refine.exceptions import CorrespondenceError
from refine.model.measured import domain_mesh
from refine.correspond.geometry import boundary_segments, segment_distances, split_outline

#: unknowns of one grip's rigid motion in 2D: translation x, y (length) and rotation as the
#: displacement of the grip's end (length: the angle times the grip's half-length)
GRIP_DOF = 3


@dataclass(frozen=True)
class Grips:
    """Which sides hold the object (data, not arguments).

    Attributes:
        clamped: sides that do not move (zero displacement), e.g. ``("left",)``.
        gripped: sides moved by an unknown rigid motion per frame, e.g. ``("right",)``.
    """

    clamped: tuple = ("left",)
    gripped: tuple = ("right",)

    @staticmethod
    def parse(text: str | None, default: tuple) -> tuple:
        """``"left,right"`` -> ``("left", "right")``; empty or None gives ``default``."""
        return tuple(s.strip() for s in text.split(",") if s.strip()) if text else default


class CloudModel:
    """A finite-element model of a bundle's domain driven by grips.

    Args:
        experiment: the bundle's experiment (a rectangle domain; kind, law, E, nu, thickness).
        grips: clamped and gripped sides.
        h: element size (length unit).
        element: element type.
    """

    def __init__(self, experiment: Experiment, grips: Grips = Grips(), h: float = 5.0, element: str = "tri3",
                 linear_solver: str = "auto"):
        if not isinstance(experiment.domain, RectangleDomain):
            raise CorrespondenceError("grips are named by the sides of a rectangle domain; give the bundle "
                                      "model.domain = { rectangle = [...] } (outlines of other shapes come later)")
        if not grips.clamped and not grips.gripped:
            raise CorrespondenceError("name at least one clamped or gripped side: a free body has rigid modes")
        self.experiment, self.grips, self.h = experiment, grips, float(h)
        self.mesh = mesh = domain_mesh(experiment, h, element)
        self.segments = boundary_segments(mesh)
        self.boundary_nodes = np.unique(self.segments)
        clamp = np.unique(np.concatenate([mesh.side(s) for s in grips.clamped] or [np.zeros(0, np.int64)]))
        self.grip_nodes = [np.setdiff1d(mesh.side(s), clamp) for s in grips.gripped]
        held = np.unique(np.concatenate([clamp, *self.grip_nodes]))
        self.clamp = clamp
        self.problem = jf.Problem(mesh, experiment.law, experiment.kind, fixed=jf.dofs(mesh, held))
        self.solver = jf.Solver(self.problem, linear_solver)
        X = mesh.nodes
        self._centres = np.array([X[n].mean(axis=0) for n in self.grip_nodes]).reshape(-1, 2)
        self._half = np.array([max(0.5 * np.ptp(X[n], axis=0).max(), 1e-9) for n in self.grip_nodes])
        self._solve_all = jax.jit(self._solve_frames)
        self.size = float(np.ptp(X, axis=0).max())

    @property
    def n_grips(self) -> int:
        return len(self.grip_nodes)

    def params(self, **kw) -> dict:
        """The initial model's parameters (the experiment's E, nu, thickness unless given)."""
        ex = self.experiment
        kw.setdefault("E", ex.E)
        kw.setdefault("nu", ex.nu)
        kw.setdefault("thickness", ex.thickness or 1.0)
        return self.problem.params(**kw)

    def prescribed(self, q):
        """``u_D`` (the held dofs' values, in ``problem.fixed`` order) of one frame's grip motion
        ``q (n_grips, 3)``: translation x, y and the rotation's displacement at the grip's end."""
        X = jnp.asarray(self.mesh.nodes)
        U = jnp.zeros_like(X)
        q = jnp.reshape(jnp.asarray(q), (self.n_grips, GRIP_DOF))
        for g, nodes in enumerate(self.grip_nodes):
            phi = q[g, 2] / self._half[g]
            c, s = jnp.cos(phi), jnp.sin(phi)
            d = X[nodes] - self._centres[g]
            moved = jnp.stack([c * d[:, 0] - s * d[:, 1], s * d[:, 0] + c * d[:, 1]], 1) + self._centres[g] + q[g, :2]
            U = U.at[nodes].set(moved - X[nodes])
        return U.reshape(-1)[self.problem.fixed]

    def solve_frames(self, theta, Q, start=None):
        """Equilibrium displacements ``(n_frames, n_nodes, 2)`` for grip motions ``Q (n_frames,
        n_grips, 3)``, each frame from the previous one's equilibrium (a ``lax.scan``, compiled once;
        differentiable in theta and Q by the implicit function theorem). ``start``: the equilibrium
        ``(u (n_nodes, 2), q (n_grips, 3))`` of the frame before the first (default: the reference);
        it is only where Newton starts."""
        return self._solve_all(theta, jnp.asarray(Q), self.start(start))

    def start(self, start=None):
        """``(u flat, u_D)`` where a solve starts: the reference, or a state ``(u, q)``."""
        if start is None:
            return jnp.zeros(self.problem.n_dofs), jnp.zeros(len(self.problem.fixed))
        u, q = start
        return jnp.asarray(u).reshape(-1), self.prescribed(q)

    def _solve_frames(self, theta, Q, start):
        U_D = jax.vmap(self.prescribed)(Q)
        rest = jax.lax.stop_gradient({"f": theta["f"], "traction": theta["traction"]})

        def step(carry, u_D):
            u_prev, uD_prev = carry
            u = self.solver.displacement({**theta, "u_D": u_D}, start=(u_prev, {"u_D": uD_prev, **rest}))
            return (jax.lax.stop_gradient(u.reshape(-1)), jax.lax.stop_gradient(u_D)), u

        return jax.lax.scan(step, jax.lax.stop_gradient(start), U_D)[1]

    def check_reference(self, cloud: np.ndarray, noise: float, tol: float) -> float:
        """How far the reference cloud (frame 0) lies from the model's outline: the 95th percentile
        of the outline points' distances (length). Raises :class:`CorrespondenceError` above ``tol``:
        the cloud is not of this object, or not in its coordinates."""
        on = split_outline(cloud, 4 * noise)
        X = self.mesh.nodes
        d = np.asarray(segment_distances(jnp.asarray(cloud[on]), X[self.segments[:, 0]], X[self.segments[:, 1]]))
        far = float(np.percentile(d.min(axis=1), 95)) if on.any() else np.inf
        if not far <= tol:
            raise CorrespondenceError(
                f"the reference cloud (frame 0) lies {far:.3g} from the model's outline (95th percentile; allowed "
                f"{tol:.3g}): the cloud does not show the domain of experiment.toml. Check its coordinates and "
                "units, or the domain")
        return far
