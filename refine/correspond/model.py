"""The model of an object seen without correspondences: a mesh of the bundle's domain (a sheet in
2D, a solid body in 3D), held at its clamped sides and moved at its gripped sides by an unknown
rigid motion per frame (3 unknowns per grip in 2D, 6 in 3D); every other boundary point is free.
The grips' motion is found from the clouds together with the model's parameters
(:mod:`refine.correspond.fit`); the free boundary and the interior follow from the equilibrium,
so every node has a position in every frame: the dense correspondences.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

import jaxfem as jf

from refine.bundle.experiment import Experiment, MeshDomain, RectangleDomain
from refine.exceptions import CorrespondenceError
from refine.model.measured import domain_mesh
from refine.correspond.geometry import boundary_facets, facet_distances, on_boundary

#: unknowns of one grip's rigid motion, by dimension: the translation (length), then the rotation
#: as the displacement of the grip's end (length: the angle, or in 3D the rotation vector, times
#: the grip's half-length): x, y, turn in 2D; x, y, z, rx, ry, rz in 3D
GRIP_DOFS = {2: 3, 3: 6}
GRIP_DOF = GRIP_DOFS[2]


def rotation(w):
    """The rotation matrix of angle ``w (1,)`` (2D) or of rotation vector ``w (3,)`` (3D, radians;
    Rodrigues' formula, smooth at zero)."""
    if w.shape[0] == 1:
        c, s = jnp.cos(w[0]), jnp.sin(w[0])
        return jnp.array([[c, -s], [s, c]])
    t2 = jnp.sum(w * w)
    small = t2 < 1e-12
    t = jnp.sqrt(jnp.where(small, 1.0, t2))
    a = jnp.where(small, 1.0 - t2 / 6.0, jnp.sin(t) / t)  # sin t / t
    b = jnp.where(small, 0.5 - t2 / 24.0, (1.0 - jnp.cos(t)) / (t * t))  # (1 - cos t) / t^2
    K = jnp.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
    return jnp.eye(3) + a * K + b * (K @ K)


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
        experiment: the bundle's experiment: a rectangle domain (2D; kind, law, E, nu, thickness)
            or a solid with a mesh domain (3D; sides are the mesh's named faces, the file's or
            experiment.toml's ``domain.faces``, and its bounding box's: left, right, bottom, top,
            back, front).
        grips: clamped and gripped sides.
        h: element size (length unit; 2D, where the domain is meshed).
        element: element type (2D).
        mesh: the model's mesh as it is (default: the domain's; a 3D domain's file is read from
            ``root``).
        root: the bundle's directory, where a mesh domain's file lies.
    """

    def __init__(self, experiment: Experiment, grips: Grips = Grips(), h: float = 5.0, element: str = "tri3",
                 linear_solver: str = "auto", mesh=None, root=None):
        if mesh is None and not isinstance(experiment.domain, (RectangleDomain, MeshDomain)):
            raise CorrespondenceError("grips are named by the sides of a rectangle domain (2D) or of a mesh's bounding "
                                      "box (3D); give the bundle model.domain = { rectangle = [...] } or a mesh")
        if not grips.clamped and not grips.gripped:
            raise CorrespondenceError("name at least one clamped or gripped side: a free body has rigid modes")
        self.experiment, self.grips, self.h = experiment, grips, float(h)
        self._built = {"element": element, "linear_solver": linear_solver, "root": root, "meshed": mesh is None}
        self.mesh = mesh = domain_mesh(experiment, h, element, root=root) if mesh is None else mesh
        if mesh.dim != experiment.dim:
            raise CorrespondenceError(f"the mesh is {mesh.dim}D but model.kind {experiment.kind!r} is "
                                      f"{experiment.dim}D")
        self.dim = mesh.dim
        self.grip_dof = GRIP_DOFS[self.dim]
        self.facets = boundary_facets(mesh)
        self.boundary_nodes = np.unique(self.facets)
        clamp = np.unique(np.concatenate([_side(mesh, s) for s in grips.clamped] or [np.zeros(0, np.int64)]))
        self.grip_nodes = [np.setdiff1d(_side(mesh, s), clamp) for s in grips.gripped]
        held = np.unique(np.concatenate([clamp, *self.grip_nodes]))
        self.clamp = clamp
        self.problem = jf.Problem(mesh, experiment.law, experiment.kind, fixed=jf.dofs(mesh, held))
        self.solver = jf.Solver(self.problem, linear_solver)
        X = mesh.nodes
        self._centres = np.array([X[n].mean(axis=0) for n in self.grip_nodes]).reshape(-1, self.dim)
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
        ``q (n_grips, grip_dof)``: the translation, then the rotation's displacement at the grip's
        end (2D: x, y, turn; 3D: x, y, z and the rotation vector times the half-length)."""
        X = jnp.asarray(self.mesh.nodes)
        U = jnp.zeros_like(X)
        q = jnp.reshape(jnp.asarray(q), (self.n_grips, self.grip_dof))
        for g, nodes in enumerate(self.grip_nodes):
            R = rotation(q[g, self.dim:] / self._half[g])
            d = X[nodes] - self._centres[g]
            U = U.at[nodes].set(d @ R.T + self._centres[g] + q[g, : self.dim] - X[nodes])
        return U.reshape(-1)[self.problem.fixed]

    def solve_frames(self, theta, Q, start=None):
        """Equilibrium displacements ``(n_frames, n_nodes, dim)`` for grip motions ``Q (n_frames,
        n_grips, grip_dof)``, each frame from the previous one's equilibrium (a ``lax.scan``, compiled once;
        differentiable in theta and Q by the implicit function theorem). ``start``: the equilibrium
        ``(u (n_nodes, dim), q (n_grips, grip_dof))`` of the frame before the first (default: the reference);
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

    def cell_size(self) -> float:
        """The mean cell's size (length): its area's or volume's root."""
        return float(np.mean(self.mesh.volumes())) ** (1.0 / self.dim)

    def coarser(self, factor: float = np.sqrt(2.0)) -> CloudModel | None:
        """The same model on a mesh about ``factor`` times coarser (kept: built once), or None where
        the mesh cannot be made again: a 2D domain is meshed at ``factor * h``; a given mesh only
        where it fills its bounding box (a block: a structured box of the same element with
        ``factor`` times fewer bricks along each axis). What a discretisation estimate refits on."""
        cache = self.__dict__.setdefault("_coarser", {})
        if factor in cache:
            return cache[factor]
        b, mesh = self._built, self.mesh
        if b["meshed"]:
            coarse = CloudModel(self.experiment, self.grips, factor * self.h, b["element"], b["linear_solver"],
                                root=b["root"])
        else:
            lo, hi = mesh.nodes.min(axis=0), mesh.nodes.max(axis=0)
            if self.dim != 3 or not np.isclose(mesh.volumes().sum(), np.prod(hi - lo), rtol=1e-9):
                cache[factor] = None
                return None
            n = [max(1, int(round(L / (factor * self.cell_size() * 6 ** (1 / 3))))) for L in hi - lo]
            coarse = CloudModel(self.experiment, self.grips, mesh=jf.box(*lo, *hi, *n, element=mesh.element),
                                linear_solver=b["linear_solver"])
        cache[factor] = coarse
        return coarse

    def boundary_distances(self, points, x=None) -> np.ndarray:
        """Distances ``(n,)`` of points ``(n, dim)`` to the model's boundary (outline in 2D, surface
        in 3D) at node positions ``x`` (default: the reference), in chunks of points."""
        x = jnp.asarray(self.mesh.nodes if x is None else x)
        facets = jnp.asarray(self.facets)
        points = np.asarray(points, float)
        step = max(1, 2_000_000 // max(len(self.facets), 1))
        return np.concatenate([np.asarray(facet_distances(jnp.asarray(points[i: i + step]), x, facets).min(axis=1))
                               for i in range(0, len(points), step)] or [np.zeros(0)])

    def check_reference(self, cloud: np.ndarray, noise: float, tol: float) -> float:
        """How far the reference cloud (frame 0) lies from the model's boundary: the 95th percentile
        of its boundary points' distances (length). Raises :class:`CorrespondenceError` above
        ``tol``: the cloud is not of this object, or not in its coordinates."""
        cloud = np.asarray(cloud, float)
        if cloud.ndim != 2 or cloud.shape[1] != self.dim:
            raise CorrespondenceError(f"the clouds are {cloud.shape[-1]}D points but the model is {self.dim}D")
        on = on_boundary(cloud, 4 * noise)
        far = float(np.percentile(self.boundary_distances(cloud[on]), 95)) if on.any() else np.inf
        if not far <= tol:
            where = "outline" if self.dim == 2 else "surface"
            raise CorrespondenceError(
                f"the reference cloud (frame 0) lies {far:.3g} from the model's {where} (95th percentile; allowed "
                f"{tol:.3g}): the cloud does not show the domain of experiment.toml. Check its coordinates and "
                "units, or the domain")
        return far


def _side(mesh, name: str) -> np.ndarray:
    """The nodes of a named face of the mesh (``mesh.faces``: the mesh file's or experiment.toml's
    ``domain.faces``) or of a side of its bounding box, with a clear error for a wrong name."""
    try:
        return mesh.side(name)
    except jf.MeshError:
        raise CorrespondenceError(f"unknown side {name!r} for a {mesh.dim}D model; name one of its faces or its "
                                  f"bounding box's sides: {', '.join(mesh.side_names())}") from None
