"""A 3D model driven by measured surface points and loaded by a measured force spread uniformly
over one face (the cup holder squeezed on its bottom), with a probe that follows a geometry morph
of a straight-edged ``tet10`` mesh.

:class:`LoadedModel` is a :class:`~refine.model.MeasuredModel` whose traction facets carry, in
frame ``f``, the pressure ``force[f] / area(X)`` (``area`` the loaded face's area at the current
geometry ``X``, so a hole cut from the face raises the pressure the same measured force makes).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

import jaxfem as jf
from jaxfem.elements import get_element
from jaxfem.probe import solve_small

from refine.exceptions import ObservationError
from refine.model.measured import MeasuredModel


def straight_tet10_pairs(mesh: jf.Mesh) -> np.ndarray:
    """``(6, 2)``: the corners each mid-edge node of a ``tet10`` cell lies between (local indices,
    read off the first cell)."""
    X = mesh.nodes[mesh.cells[0]]
    pairs = []
    for m in range(4, 10):
        d = [np.linalg.norm(0.5 * (X[a] + X[b]) - X[m]) for a in range(4) for b in range(a + 1, 4)]
        k = int(np.argmin(d))
        pairs.append([(a, b) for a in range(4) for b in range(a + 1, 4)][k])
    return np.asarray(pairs)


def moved_probe(probe: jf.Probe, X, points) -> jf.Probe:
    """``probe`` after a morph of the nodes to ``X (n_nodes, 3)`` for the same physical ``points
    (n, 3)``: linear tetrahedra as :meth:`jaxfem.Probe.moved`; ``tet10`` with straight edges (the
    morphs of :mod:`refine.solid.morph` keep mid-edge nodes at their edges' middles) from the
    corners' barycentric coordinates, exact for such cells. Differentiable in ``X``."""
    if probe.nodes.shape[1] == 4:
        return probe.moved(X, points)
    Xe = jnp.asarray(X)[probe.nodes[:, :4]]
    T = jnp.swapaxes(Xe[:, 1:] - Xe[:, :1], 1, 2)
    lam = solve_small(T, jnp.asarray(points) - Xe[:, 0])  # closed form: no batched LAPACK (see solve_small)
    return jf.Probe(probe.cells, probe.nodes, get_element("tet10").shape(lam))


def face_area(X, facets) -> jnp.ndarray:
    """Area of the boundary ``facets`` (their corner triangles) at nodes ``X (n_nodes, 3)``."""
    xp = jnp if isinstance(X, jax.core.Tracer) else np  # concrete: no small program compiled per mesh
    X = xp.asarray(X)
    a, b, c = X[facets[:, 0]], X[facets[:, 1]], X[facets[:, 2]]
    return 0.5 * xp.linalg.norm(xp.cross(b - a, c - a), axis=1).sum()


class LoadedModel(MeasuredModel):
    """A 3D model driven by its measured boundary points (on the surface) and loaded by a measured
    total ``force (n_frames, 3)`` (the bundle's force unit) spread uniformly over ``facets`` (dead
    load per reference area). ``mesh`` must have straight edges where it is morphed.

    ``driven``: the surface nodes the boundary points drive ``(k,)`` (each interpolated from its
    nearest points, :func:`jaxfem.surface.surface_interpolation`), e.g. every node of the face a
    fixture holds; None: those within 0.75 point spacings of a boundary point (which leaves nodes
    between rows of points free: the cup holder's rim between its rings of points).

    ``headroom``: the solver's padding holds a mesh this many times larger (:class:`jaxfem.Solver`),
    so the holed meshes built after it share its compiled programs.

    The other arguments are :class:`~refine.model.MeasuredModel`'s; the points are compared with
    the model where :func:`refine.model.boundary.place_surface_points` puts them (on the surface, within
    the placement's tolerance)."""

    def __init__(self, experiment, observations, mesh: jf.Mesh, facets, force, h: float | None = None,
                 linear_solver: str = "auto", driven=None, headroom: float = 1.0):
        force = np.asarray(force, float).reshape(observations.n_frames, 3)
        if not np.isfinite(force).all():
            raise ObservationError("the measured forces must be finite numbers in every frame")
        self.force = force
        self.facets = np.asarray(facets, np.int64)
        self.driven = None if driven is None else np.asarray(driven, np.int64)
        super().__init__(experiment, observations, mesh=mesh, h=h, linear_solver=linear_solver,
                         traction_facets=self.facets, headroom=headroom)

    def _interpolation(self, points, nodes=None, names=None):
        """:meth:`MeasuredModel._interpolation` onto :attr:`driven` where given."""
        return super()._interpolation(points, nodes=self.driven if nodes is None else nodes, names=names)

    def tractions(self, X) -> jnp.ndarray:
        """``(n_frames, n_loaded, 3)``: each frame's pressure on the loaded face at geometry ``X``
        (numpy where ``X`` is concrete), the same on each of its facets (the solver pads the
        facets to a bucket, so another count of them compiles no solve again: :mod:`jaxfem.padding`)."""
        per_area = self.force / face_area(X, self.facets)
        return per_area[:, None, :] * np.ones((1, len(self.facets), 1))

    def frame_tractions(self, X) -> jnp.ndarray:
        """:meth:`tractions`: the frame-by-frame solves on :mod:`jaxfem.program`'s shared programs
        (:class:`~refine.model.objective.Compiled`, :meth:`predict`, the drive's pull-back) load
        each frame with it."""
        return self.tractions(X)

    @property
    def shares_programs(self) -> bool:
        """True: concrete parameters are solved frame by frame on the solver's shared programs,
        each frame loaded by :meth:`frame_tractions` (a remesh compiles no solve again); traced
        ones (forward or reverse mode through :meth:`predict`) by :meth:`_solve_frames`' scan."""
        return True

    def _solve_frames(self, theta, B, frames=None):
        frames = tuple(range(self.obs.n_frames)) if frames is None else frames
        U_D = jnp.stack([jnp.asarray(self.drives[f].matrix) @ B[f] for f in frames])
        T = self.tractions(theta["X"])[jnp.asarray(frames)]
        f_ext = jax.lax.stop_gradient(theta["f"])

        def step(carry, load):
            u_prev, uD_prev, t_prev = carry
            u_D, t = load
            u = self.solver.displacement({**theta, "u_D": u_D, "traction": t},
                                         start=(u_prev, {"u_D": uD_prev, "f": f_ext, "traction": t_prev}))
            stop = jax.lax.stop_gradient
            return (stop(u.reshape(-1)), stop(u_D), stop(t)), u

        start = (jnp.zeros(self.problem.n_dofs), jnp.zeros_like(U_D[0]), jnp.zeros_like(T[0]))
        return jax.lax.scan(step, start, (U_D, T))[1]

    def at_points(self, U, theta):
        return jax.vmap(moved_probe(self.probe, theta["X"], self.positions))(U)
