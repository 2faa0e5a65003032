"""The finite-element model of a measurement: a mesh over the bundle's domain, driven frame by
frame by the measured motion of the boundary points (the paper's set P), predicting every
tracked point.

This is where ``refine`` joins ``jaxfem`` and the observations: :meth:`MeasuredModel.predict`
is a differentiable function of the model parameters (moduli per cell, thickness, nu, geometry),
so any misfit between predicted and measured points can be minimised by gradients.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property, partial

import jax
import jax.numpy as jnp
import numpy as np

import jaxfem as jf
from jaxfem.padding import BATCH, pad_batch

from refine.exceptions import ObservationError
from refine.bundle.experiment import Experiment, FromPointsDomain, MeshDomain, RectangleDomain
from refine.bundle.outline import resolve_domain
from refine.bundle.sides import with_domain_faces
from refine.model.interpolation import PaddedProbe, padded_probe, points, points_and_derivatives
from refine.model.boundary import (boundary_face_nodes, outline_tolerance, place_points, place_surface_points,
                                   side_nodes)
from refine.bundle.roles import point_spacing
from refine.bundle.observations import Observations
from refine.model.known import cell_parameters, hole_geometry, known_inclusions, model_material


def _traced(*trees) -> bool:
    return any(isinstance(x, jax.core.Tracer) for x in jax.tree.leaves(trees))


def grid_spacing(points: np.ndarray) -> float:
    """Median nearest-neighbour distance of the tracked points (length unit)."""
    return point_spacing(points)


def domain_mesh(experiment: Experiment, h: float, element: str = "tri3", inclusions=(), holes=(),
                root=None) -> jf.Mesh:
    """A mesh of the experiment's domain with target element size ``h``, minus the domain's known
    holes, following its known regions (tagged ``known:NAME``); optional inclusions (tagged 1,
    2, ... in their order) and further holes (``jaxfem.Ellipse``/``Rect``) are followed too. A domain built from the points must be resolved first
    (:func:`refine.bundle.outline.resolve_domain`; :class:`MeasuredModel` does it)."""
    dom = experiment.domain
    if isinstance(dom, FromPointsDomain):
        raise ObservationError("a domain built from the points needs them: resolve it first "
                               "(refine.bundle.outline.resolve_domain(experiment, observations))")
    if isinstance(dom, MeshDomain):
        path = dom.path if root is None else f"{root}/{dom.path}"
        return with_domain_faces(jf.read_mesh(path), dom.faces)  # experiment.toml's named faces added
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


def frame_traction(T, frame: int) -> dict:
    """The loads of ``frame`` from :meth:`MeasuredModel.frame_tractions` ``T``: ``{"traction":
    T[frame]}``, none where ``T`` is None (the parameter ``traction`` holds in every frame)."""
    return {} if T is None else {"traction": T[frame]}


@dataclass(frozen=True, eq=False)
class FrameDrive:
    """How one frame's boundary motion is imposed: prescribed values = ``matrix @ U_boundary``.

    Attributes:
        matrix: ``(n_fixed, n_boundary_points * dim)``; columns of points lost in this frame are zero.
    """

    matrix: np.ndarray


class MeasuredModel:
    """A finite-element model driven by measured boundary points.

    Boundary points within :func:`~refine.model.boundary.outline_tolerance` of the outline drive
    it where they project onto it (:mod:`refine.model.boundary`); a domain built from the points
    is resolved to its polygon here (:attr:`experiment` holds it).

    Args:
        experiment: the bundle's experiment (domain, known regions and holes, kinematics, initial
            law, E, nu, thickness).
        observations: the tracked points and their displacements.
        mesh: the mesh to use (default: the experiment's ``model.mesh`` file where it has one and
            no ``h`` is given, else a mesh of the domain at ``h``, half the grid spacing by default,
            that follows its known regions and holes).
        element: element type of the default mesh.
        linear_solver: see :mod:`jaxfem.linsolve`.
        traction_facets: boundary facets that carry the parameter ``traction`` (a dead load; a
            subclass such as :class:`refine.solid.LoadedModel` sets it per frame).
        headroom: the solver's padding holds a mesh this many times larger (``jaxfem.Solver``),
            so that larger meshes of the same kind built later share its compiled programs.
    """

    def __init__(self, experiment: Experiment, observations: Observations, mesh: jf.Mesh | None = None,
                 element: str = "tri3", h: float | None = None, linear_solver: str = "auto", root=None,
                 traction_facets=None, headroom: float = 1.0):
        if observations.dim != 2 and mesh is None and not isinstance(experiment.domain, MeshDomain):
            raise ObservationError("3D bundles need a mesh (domain = { mesh = ... })")
        experiment = resolve_domain(experiment, observations)
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
        place = place_points if self.mesh.dim == 2 else partial(place_surface_points, domain=experiment.domain)
        self.placement = place(self.mesh, observations.reference, observations.roles == "boundary", observations.ids,
                               outline_tolerance(self.spacing, experiment.noise_std))
        self.positions = self.placement.positions  # where each point is compared with the model
        self._face_nodes = boundary_face_nodes(self.mesh, experiment.domain)  # 3D: every node of boundary_faces
        loop, _ = self._interpolation(self._driving_points(), names=observations.ids[self.boundary])
        self.loop = loop
        dim = self.mesh.dim
        self.problem = jf.Problem(self.mesh, model_material(experiment), experiment.kind,
                                  fixed=jf.dofs(self.mesh, loop), traction_facets=traction_facets)
        self.linear_solver = linear_solver  # as asked ("auto" included): models derived from this one ask the same
        self.solver = jf.Solver(self.problem, linear_solver, headroom=headroom)
        # 3D: a point projected onto a flat piece of a curved quadratic face may lie a chord's
        # sagitta outside its cell (the placement checked its distance)
        self.probe = jf.locate(self.mesh, self.positions, tol=1e-6 if dim == 2 else 1e-2, names=observations.ids)
        forces = observations.forces
        self.sides = {e: side_nodes(self.mesh, experiment.domain, e) for e in (forces.edges if forces else ())}
        self.drives = [self._drive(f) for f in range(observations.n_frames)]
        self._dim = dim
        self._solve_all = jax.jit(self._solve_frames)  # traced and compiled once per model

    # ------------------------------------------------------------------ boundary drive
    def _interpolation(self, points, nodes=None, names=None):
        """``(nodes, W)``: the driven nodes and the map from boundary-point values to them; along the
        outline in 2D, on the surface near the points in 3D (:func:`jaxfem.surface.surface_interpolation`,
        nodes within 0.75 point spacings; ``nodes`` fixed once chosen, so lost points only change W)."""
        if self.mesh.dim == 2:
            # no tolerance: the placement checked the points' offsets from the outline
            return jf.boundary_interpolation(self.mesh, points, tol=np.inf, names=names)
        from jaxfem.surface import surface_interpolation

        nodes = self._face_nodes if nodes is None else nodes
        return surface_interpolation(self.mesh, points, 0.75 * self.spacing, nodes=nodes, names=names)

    def _driving_points(self) -> np.ndarray:
        """Where the boundary points drive the model: their reference positions in 2D (the outline
        interpolation projects them itself), their projections onto the surface in 3D."""
        src = self.obs.reference if self.mesh.dim == 2 else self.positions
        return src[self.boundary]

    def _drive(self, frame: int) -> FrameDrive:
        obs, dim = self.obs, self.mesh.dim
        valid = obs.valid[frame, self.boundary]
        if valid.sum() < 3:
            raise ObservationError(f"frame {frame + 1}: only {int(valid.sum())} boundary points were tracked; "
                                   "at least 3 are needed to drive the model")
        idx = np.flatnonzero(valid)
        _, W = self._interpolation(self._driving_points()[idx], nodes=getattr(self, "loop", None))
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
        B = self.measured_boundary() if boundary is None else boundary
        if self.shares_programs and not _traced(theta, B):  # frame by frame on the solver's shared program
            return jax.device_put(self._solve_eager(theta, np.asarray(B), frames))
        B = jnp.asarray(B)
        if frames is None:
            return self._solve_all(theta, B)
        return self._solve_frames(theta, B, tuple(frames))

    @property
    def shares_programs(self) -> bool:
        """Whether the frames are solved as here (a subclass that loads its frames otherwise, e.g.
        :class:`refine.solid.LoadedModel`, is solved by its own ``_solve_frames``, compiled per
        model); then concrete parameters are solved frame by frame on the solver's shared
        programs (:mod:`jaxfem.program`), which compiles nothing per model."""
        return type(self)._solve_frames is MeasuredModel._solve_frames

    def frame_tractions(self, X):
        """Each frame's traction on the traction facets at the reference nodes ``X``, ``(n_frames,
        n_facets, dim)``, where a subclass loads its frames so (:class:`refine.solid.LoadedModel`:
        a measured force over a face's area at ``X``); None here: the parameter ``traction`` in every
        frame. The frame-by-frame solves on the shared programs take it (:func:`frame_traction`)."""
        return None

    def frame_starts(self, theta):
        """Where each frame's solve starts: ``(u0 (n_dofs,), loads0)``, the undeformed state of the
        first frame's loads other than ``u_D``; later frames start from the one before."""
        return np.zeros(self.problem.n_dofs), {"u_D": np.zeros(len(self.problem.fixed)), "f": theta["f"],
                                               "traction": theta["traction"]}

    def _solve_eager(self, theta, B, frames=None):
        frames = range(self.obs.n_frames) if frames is None else frames
        start, out, T = self.frame_starts(theta), [], self.frame_tractions(theta["X"])
        for f in frames:
            loads = {"u_D": self.drives[f].matrix @ B[f], **frame_traction(T, f)}
            u = np.asarray(self.solver.displacement({**theta, **loads}, start=start))
            start = (u.reshape(-1), {**start[1], **loads})
            out.append(u)
        return np.stack(out)

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

    def raise_solve_failure(self, theta) -> None:
        """Solve the frames one by one with the solver's checks and raise its
        :class:`jaxfem.SolverError` (``nonlinear solve failed at load step ...``, as ``nonrigid
        simulate`` gives it), naming the frame: for a model whose :meth:`predict` is not finite."""
        start = None
        for f in range(self.obs.n_frames):
            th = {**theta, "u_D": self.prescribed(f)}
            try:
                sol = self.solver.solve(th, start=start)
            except jf.SolverError as e:
                raise jf.SolverError(f"frame {f + 1} of {self.obs.n_frames}, the model driven by the measured boundary "
                                     f"points: {e}", step=e.step, load_factor=e.load_factor, reason=e.reason) from None
            start = (sol.u.reshape(-1), {"u_D": th["u_D"], "f": th["f"], "traction": th["traction"]})
        raise jf.SolverError("the model's predictions are not finite although every frame solved",
                             step=0, load_factor=0.0, reason="nan")

    def predict(self, theta, frames=None, boundary=None):
        """Predicted displacements of every tracked point, ``(n_frames, n_points, dim)``."""
        return self.at_points(self.solve_frames(theta, frames, boundary), theta)

    def boundary_jacobian(self, theta) -> np.ndarray:
        """Derivatives of the prediction ``(n_frames, n_points, dim)`` with respect to the measured
        boundary displacements ``(n_frames, n_boundary * dim)``, as ``(n_frames, n_points, dim,
        n_frames, n_boundary * dim)`` (:func:`refine.model.drive.boundary_jacobian`)."""
        from refine.model.drive import boundary_jacobian

        return boundary_jacobian(self, theta)

    def boundary_vjp(self, theta, cotangents) -> np.ndarray:
        """Cotangents of the measured boundary displacements ``(c, n_frames, n_boundary * dim)``
        from ``c`` cotangents of the prediction ``(c, n_frames, n_points, dim)``
        (:func:`refine.model.drive.boundary_vjp`)."""
        from refine.model.drive import boundary_vjp

        return boundary_vjp(self, theta, cotangents)

    @cached_property
    def points_vjp(self):
        """``(U, X, C) -> (c, n_frames, n_nodes, dim)``, compiled once per model: the pull-back
        of :meth:`at_points` (nodal displacements ``U (n_frames, n_nodes, dim)`` at the tracked
        points of a mesh at ``X``) of ``c`` cotangents ``C (c, n_frames, n_points, dim)``."""
        def f(U, X, C):
            _, pull = jax.vjp(lambda UU: self.at_points(UU, {"X": X}), U)
            return jax.vmap(lambda c: pull(c)[0])(C)
        return jax.jit(f)

    def at_points_and_derivatives(self, U, dU, X, dX):
        """:meth:`at_points` of ``U (n_frames, n_nodes, dim)`` and its derivatives along ``k``
        directions ``dU (k, n_frames, n_nodes, dim)``, ``dX (k, n_nodes, dim)`` (host numpy),
        ``(n_frames, n_points, dim)`` and ``(k, n_frames, n_points, dim)``; by :attr:`points_jvp`
        in batches of ``jaxfem.padding.BATCH`` directions (one program for any k), on the program
        shared by models of about this size (:mod:`refine.model.interpolation`) where the model
        interpolates on simplices, else on this model's own :attr:`points_jvp`."""
        pp = self._padded_probe
        if pp is not None:
            return points_and_derivatives(pp, U, dU, X, dX)
        k = len(dU)
        dU, dX = pad_batch(dU, k), pad_batch(dX, k)
        out = [self.points_jvp(U, dU[i: i + BATCH], X, dX[i: i + BATCH]) for i in range(0, len(dU), BATCH)]
        return np.asarray(out[0][0]), np.concatenate([np.asarray(d) for _, d in out])[:k]

    @cached_property
    def _padded_probe(self) -> PaddedProbe | None:
        """The probe's arrays for the interpolation program shared by models of about this size
        (:mod:`refine.model.interpolation`), padded as the solver's arrays are; ``None`` where
        this model interpolates its own way (no candidate cells, or a subclass's :meth:`at_points`)."""
        if (type(self).at_points is not MeasuredModel.at_points or self.probe.neighbours is None
                or self.mesh.element not in ("tri3", "tet4", "tri6")):
            return None
        s = getattr(getattr(self, "solver", None), "sizes", None)
        n_nodes_p, n_cells_p = (s.n_nodes_p, s.n_cells_p) if s is not None else (self.mesh.n_nodes, self.mesh.n_cells)
        return padded_probe(self.probe, self.positions, self.mesh.n_nodes, n_nodes_p, n_cells_p)

    @cached_property
    def points_jvp(self):
        """``(U, dU, X, dX) -> (at points, its derivatives)``, compiled once per model (used
        where :mod:`refine.model.interpolation`'s shared program does not apply): the
        nodal displacements ``U (n_frames, n_nodes, dim)`` at every tracked point (:meth:`at_points`)
        and its derivatives along ``k`` directions ``dU (k, n_frames, n_nodes, dim)``, ``dX (k,
        n_nodes, dim)`` of the displacements and the reference nodes (a morph moves the points'
        cells), ``(k, n_frames, n_points, dim)``."""
        def f(U, dU, X, dX):
            at = lambda U, X: self.at_points(U, {"X": X})  # noqa: E731
            pred = at(U, X)
            return pred, jax.vmap(lambda a, b: jax.jvp(at, (U, X), (a, b))[1])(dU, dX)
        return jax.jit(f)

    def at_points(self, U, theta):
        """Nodal displacements ``U (n_frames, n_nodes, dim)`` (from :meth:`solve_frames`) at every
        tracked point, ``(n_frames, n_points, dim)``: for callers that also need the nodal
        solution (reaction forces in :mod:`refine.diagnosis.forces`, strain maps), so they solve once."""
        pp = self._padded_probe
        if pp is not None and not _traced(U, theta["X"]):  # concrete: the program shared by models of this size
            return points(pp, U, theta["X"])
        probe = self.probe
        if self.mesh.element in ("tri3", "tet4", "tri6"):  # follow a geometry morph of the reference nodes
            probe = probe.moved(theta["X"], self.positions)
        return jax.vmap(probe)(U)
