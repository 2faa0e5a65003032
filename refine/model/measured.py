"""The finite-element model of a measurement: a mesh over the bundle's domain, driven frame by
frame by the measured motion of the boundary points (the paper's set P), predicting every
tracked point.

This is where ``refine`` joins ``jaxfem`` and the observations: :meth:`MeasuredModel.predict`
is a differentiable function of the model parameters (moduli per cell, thickness, nu, geometry),
so any misfit between predicted and measured points can be minimised by gradients.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

import jaxfem as jf

from refine.exceptions import ObservationError
from refine.bundle.experiment import Experiment, MeshDomain, RectangleDomain
from refine.bundle.roles import point_spacing
from refine.bundle.observations import Observations
from refine.model.known import cell_parameters, hole_geometry, known_inclusions, model_material


def grid_spacing(points: np.ndarray) -> float:
    """Median nearest-neighbour distance of the tracked points (length unit)."""
    return point_spacing(points)


def domain_mesh(experiment: Experiment, h: float, element: str = "tri3", inclusions=(), holes=(),
                root=None) -> jf.Mesh:
    """A mesh of the experiment's domain with target element size ``h``, minus the domain's known
    holes, following its known regions (tagged ``known:NAME``); optional inclusions (tagged 1,
    2, ... in their order) and further holes (``jaxfem.Ellipse``/``Rect``) are followed too."""
    dom = experiment.domain
    if isinstance(dom, MeshDomain):
        path = dom.path if root is None else f"{root}/{dom.path}"
        return jf.read_mesh(path)
    holes = [*(hole_geometry(v) for v in dom.holes), *holes]
    if experiment.regions:
        named = dict(inclusions) if isinstance(inclusions, dict) else {
            f"inclusion{k + 1}": s for k, s in enumerate(inclusions)}
        inclusions = {**named, **known_inclusions(experiment)}
    if isinstance(dom, RectangleDomain):
        if not inclusions and not holes:
            nx = max(2, int(round((dom.xmax - dom.xmin) / h)))
            ny = max(2, int(round((dom.ymax - dom.ymin) / h)))
            return jf.rectangle(dom.xmin, dom.ymin, dom.xmax, dom.ymax, nx, ny, element)
        return jf.plate(dom.xmin, dom.ymin, dom.xmax, dom.ymax, h, holes=holes, inclusions=inclusions,
                        element=element)
    from jaxfem.mesher import domain
    from jaxfem.shapes import Polygon as Outline

    return domain(Outline(np.asarray(dom.vertices)), h, holes=holes, inclusions=inclusions, element=element)


@dataclass(frozen=True, eq=False)
class FrameDrive:
    """How one frame's boundary motion is imposed: prescribed values = ``matrix @ U_boundary``.

    Attributes:
        matrix: ``(n_fixed, n_boundary_points * dim)``; columns of points lost in this frame are zero.
    """

    matrix: np.ndarray


class MeasuredModel:
    """A finite-element model driven by measured boundary points.

    Args:
        experiment: the bundle's experiment (domain, known regions and holes, kinematics, initial
            law, E, nu, thickness).
        observations: the tracked points and their displacements.
        mesh: the mesh to use (default: the experiment's ``model.mesh`` file where it has one and
            no ``h`` is given, else a mesh of the domain at ``h``, half the grid spacing by default,
            that follows its known regions and holes).
        element: element type of the default mesh.
        linear_solver: see :mod:`jaxfem.linsolve`.
    """

    def __init__(self, experiment: Experiment, observations: Observations, mesh: jf.Mesh | None = None,
                 element: str = "tri3", h: float | None = None, linear_solver: str = "auto", root=None):
        if observations.dim != 2 and mesh is None:
            raise ObservationError("3D bundles need a mesh (domain = { mesh = ... })")
        self.experiment, self.obs = experiment, observations
        self.spacing = grid_spacing(observations.reference)
        self.h = h or 0.5 * self.spacing
        if mesh is None and h is None and experiment.mesh is not None:
            mesh = jf.read_mesh(experiment.mesh if root is None else f"{root}/{experiment.mesh}")
        self.mesh = mesh if mesh is not None else domain_mesh(experiment, self.h, element, root=root)
        self.boundary = np.flatnonzero(observations.roles == "boundary")
        if len(self.boundary) < 3:
            raise ObservationError(f"only {len(self.boundary)} boundary points: at least 3 are needed to "
                                   "drive the model")
        loop, _ = jf.boundary_interpolation(self.mesh, observations.reference[self.boundary],
                                            tol=0.05 * self.spacing, names=observations.ids[self.boundary])
        self.loop = loop
        dim = self.mesh.dim
        self.problem = jf.Problem(self.mesh, model_material(experiment), experiment.kind,
                                  fixed=jf.dofs(self.mesh, loop))
        self.solver = jf.Solver(self.problem, linear_solver)
        self.probe = jf.locate(self.mesh, observations.reference, names=observations.ids)
        self.drives = [self._drive(f) for f in range(observations.n_frames)]
        self._dim = dim
        self._solve_all = jax.jit(self._solve_frames)  # traced and compiled once per model

    # ------------------------------------------------------------------ boundary drive
    def _drive(self, frame: int) -> FrameDrive:
        obs, dim = self.obs, self.mesh.dim
        valid = obs.valid[frame, self.boundary]
        if valid.sum() < 3:
            raise ObservationError(f"frame {frame + 1}: only {int(valid.sum())} boundary points were tracked; "
                                   "at least 3 are needed to drive the model")
        idx = np.flatnonzero(valid)
        _, W = jf.boundary_interpolation(self.mesh, obs.reference[self.boundary[idx]], tol=0.05 * self.spacing)
        # node values (n_loop, dim) = W @ U[idx]; flatten to the fixed-dof order (node-major)
        n_b = len(self.boundary)
        M = np.zeros((len(self.loop) * dim, n_b * dim))
        for c in range(dim):
            M[c::dim, idx * dim + c] = W
        order = np.argsort(jf.dofs(self.mesh, self.loop))  # problem.fixed is sorted
        return FrameDrive(M[order])

    def boundary_displacements(self, frame: int) -> np.ndarray:
        """Measured boundary displacements of a frame, flattened ``(n_boundary * dim,)``; lost = 0
        (their columns in the drive matrix are zero, so they never enter)."""
        U = self.obs.displacements[frame, self.boundary]
        return np.nan_to_num(U, nan=0.0).reshape(-1)

    def prescribed(self, frame: int, boundary_u=None):
        """``u_D`` of a frame from (measured or given) boundary displacements."""
        b = self.boundary_displacements(frame) if boundary_u is None else boundary_u
        return jnp.asarray(self.drives[frame].matrix) @ b

    # ------------------------------------------------------------------ parameters and prediction
    def params(self, E=None, nu=None, thickness=None, **kw) -> dict:
        """Parameters of the initial model (the experiment's E, nu, thickness unless given; the
        background modulus ``E`` scales the known regions' relative moduli)."""
        ex = self.experiment
        background = ex.E if E is None else E
        if ex.regions:  # a given background modulus scales the relative ones
            cellwise = cell_parameters(self.mesh, ex, float(background))
        else:  # (E may be an array or traced)
            cellwise = {**cell_parameters(self.mesh, ex, ex.E), "E": background}
        return self.problem.params(nu=ex.nu if nu is None else nu,
                                   thickness=(ex.thickness or 1.0) if thickness is None else thickness,
                                   **{**cellwise, **kw})

    def measured_boundary(self) -> np.ndarray:
        """Measured boundary displacements of every frame, ``(n_frames, n_boundary * dim)`` (lost = 0)."""
        return np.stack([self.boundary_displacements(f) for f in range(self.obs.n_frames)])

    def solve_frames(self, theta, frames=None, boundary=None):
        """Equilibrium displacements ``(n_frames, n_nodes, dim)`` for the given frames (default all).

        Each frame starts from the previous one's equilibrium (not differentiated: only the final
        equilibrium of each frame matters for a hyperelastic material). A ``lax.scan`` over the
        frames, compiled once per model. ``boundary`` replaces the measured boundary displacements
        ``(n_frames, n_boundary * dim)`` (e.g. to propagate their noise).
        """
        B = jnp.asarray(self.measured_boundary() if boundary is None else boundary)
        if frames is None:
            return self._solve_all(theta, B)
        return self._solve_frames(theta, B, tuple(frames))

    def _solve_frames(self, theta, B, frames=None):
        frames = tuple(range(self.obs.n_frames)) if frames is None else frames
        U_D = jnp.stack([jnp.asarray(self.drives[f].matrix) @ B[f] for f in frames])
        rest = jax.lax.stop_gradient({"f": theta["f"], "traction": theta["traction"]})

        def step(carry, u_D):
            u_prev, uD_prev = carry
            u = self.solver.displacement({**theta, "u_D": u_D}, start=(u_prev, {"u_D": uD_prev, **rest}))
            return (jax.lax.stop_gradient(u.reshape(-1)), jax.lax.stop_gradient(u_D)), u

        start = (jnp.zeros(self.problem.n_dofs), jnp.zeros_like(U_D[0]))
        return jax.lax.scan(step, start, U_D)[1]

    def predict(self, theta, frames=None, boundary=None):
        """Predicted displacements of every tracked point, ``(n_frames, n_points, dim)``."""
        return self.at_points(self.solve_frames(theta, frames, boundary), theta)

    def at_points(self, U, theta):
        """Nodal displacements ``U (n_frames, n_nodes, dim)`` (from :meth:`solve_frames`) at every
        tracked point, ``(n_frames, n_points, dim)``: for callers that also need the nodal
        solution (reaction forces in :mod:`refine.diagnosis.forces`, strain maps), so they solve once."""
        probe = self.probe
        if self.mesh.element in ("tri3", "tet4", "tri6"):  # follow a geometry morph of the reference nodes
            probe = probe.moved(theta["X"], self.obs.reference)
        return jax.vmap(probe)(U)
