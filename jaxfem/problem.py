"""A boundary-value problem: mesh, material law, kinematics, which dofs are prescribed, which
facets carry loads; and its parameters as one differentiable pytree.

The split is deliberate: a :class:`Problem` is static (it fixes shapes and the sparsity pattern),
its parameters are data. Changing a modulus field, a thickness, the prescribed boundary motion, a
load or the nodal coordinates never recompiles anything.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import jax
import jax.numpy as jnp
import numpy as np

from . import _config  # noqa: F401
from .exceptions import ProblemError
from .kinematics import KINDS
from .materials import Material, get_material
from .mesh import Mesh, check_orientation

#: parameter names that are loads (interpolated along a load path); the rest are fixed in a solve
LOAD_KEYS = ("u_D", "f", "traction")


def dofs(mesh: Mesh, nodes, components=None) -> np.ndarray:
    """Global dof indices of ``nodes`` (node * dim + component) for the given components (all by default)."""
    nodes = np.atleast_1d(np.asarray(nodes, np.int64))
    comps = np.arange(mesh.dim) if components is None else np.atleast_1d(components)
    return (nodes[:, None] * mesh.dim + comps[None, :]).ravel()


def _rigid_modes(X: np.ndarray) -> np.ndarray:
    """Rigid-body modes of a point cloud, ``(n_dofs, 3 or 6)``."""
    n, dim = X.shape
    c = X - X.mean(0)
    modes = [np.tile(np.eye(dim)[i], n) for i in range(dim)]
    if dim == 2:
        modes.append(np.stack([-c[:, 1], c[:, 0]], 1).ravel())
    else:
        for a, b in ((0, 1), (1, 2), (2, 0)):
            m = np.zeros((n, 3))
            m[:, a], m[:, b] = -c[:, b], c[:, a]
            modes.append(m.ravel())
    return np.stack(modes, 1)


#: 3D elements that lock when nearly incompressible, and the Poisson's ratio from which they are refused
LOCKING_3D, LOCKING_NU = ("tet4", "hex8"), 0.45


def _check_nu(nu, problem) -> None:
    """Refuse a Poisson's ratio outside (-1, 0.5), and nu >= 0.45 with linear 3D elements (they lock:
    tests/test_verify_locking3d.py). Values under a JAX trace are not checked (nothing concrete)."""
    try:
        v = np.asarray(nu, np.float64)
    except (jax.errors.TracerArrayConversionError, jax.errors.ConcretizationTypeError):
        return
    if not np.all((v > -1.0) & (v < 0.5)):
        raise ProblemError(f"Poisson's ratio must lie in (-1, 0.5), got {v.min() if v.ndim else v:g}..{v.max():g}; "
                           "nu = 0.5 is incompressible, which a displacement formulation cannot represent: "
                           "use nu <= 0.499 (with tet10 or tri6 elements)")
    if problem.kinematics == "solid" and problem.mesh.element in LOCKING_3D and np.any(v >= LOCKING_NU):
        raise ProblemError(f"nu = {v.max():g} with {problem.mesh.element} elements: linear 3D elements lock when "
                           f"nearly incompressible (nu >= {LOCKING_NU}; on a 3D Cook's membrane hex8 is 16-62 % "
                           "too stiff at nu = 0.45-0.499, tet4 39-67 %); use quadratic tetrahedra: "
                           "jaxfem.to_quadratic(mesh) of a tet4 mesh, or box(..., element='tet10')")


def _full(v, shape) -> jax.Array:
    """``v`` as a float64 device array broadcast to ``shape``: traced, by ``jnp``; else on the host
    and put on the device (an eager ``jnp`` operation compiles a small program per shape)."""
    if isinstance(v, jax.core.Tracer):
        return jnp.broadcast_to(jnp.asarray(v, jnp.float64), shape)
    return jax.device_put(np.array(np.broadcast_to(np.asarray(v, np.float64), shape)))


@dataclass(frozen=True, eq=False)
class Problem:
    """A static description of a solid-mechanics problem.

    Args:
        mesh: the mesh (its ``nodes`` are the default reference coordinates).
        material: a :class:`~jaxfem.materials.Material` or a law name (``"neo-hookean"``...).
        kinematics: ``"plane-stress"``, ``"plane-strain"`` (2D) or ``"solid"`` (3D); 2D defaults to
            plane stress, the thin-sheet case.
        fixed: dofs whose displacement is prescribed (see :func:`dofs`); their values are the
            parameter ``u_D`` in the order of ``problem.fixed`` (sorted, unique).
        traction_facets: boundary facets that carry a distributed dead load (parameter
            ``traction``, one vector per facet: force per length in 2D, per area in 3D).
    """

    mesh: Mesh
    material: Material | str = "neo-hookean"
    kinematics: str | None = None
    fixed: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    traction_facets: np.ndarray | None = None

    def __post_init__(self):
        object.__setattr__(self, "material", get_material(self.material))
        kind = self.kinematics or ("plane-stress" if self.mesh.dim == 2 else "solid")
        if kind not in KINDS:
            raise ProblemError(f"unknown kinematics {kind!r}; known: {', '.join(KINDS)}")
        if (kind == "solid") != (self.mesh.dim == 3):
            raise ProblemError(f"kinematics {kind!r} does not fit a {self.mesh.dim}D mesh")
        object.__setattr__(self, "kinematics", kind)
        fixed = np.unique(np.asarray(self.fixed, np.int64))
        if fixed.size and (fixed[0] < 0 or fixed[-1] >= self.mesh.n_dofs):
            raise ProblemError(f"fixed dof {fixed[-1]} is outside the mesh's {self.mesh.n_dofs} dofs")
        object.__setattr__(self, "fixed", fixed)
        tf = self.traction_facets
        object.__setattr__(self, "traction_facets",
                           np.zeros((0, 2 if self.mesh.dim == 2 else 3), np.int64) if tf is None
                           else np.asarray(tf, np.int64))
        check_orientation(self.mesh)
        self._check_constrained()

    def _check_constrained(self):
        # A body with a free rigid mode has a singular tangent: say so before any solve.
        modes = _rigid_modes(self.mesh.nodes)[self.fixed]
        rank = np.linalg.matrix_rank(modes, tol=1e-9 * max(1.0, np.abs(modes).max(initial=0)))
        need = modes.shape[1]
        if rank < need:
            names = ["translation x", "translation y", "translation z"][: self.mesh.dim]
            names += ["rotation"] if self.mesh.dim == 2 else ["rotation xy", "rotation yz", "rotation zx"]
            free = [n for i, n in enumerate(names) if np.linalg.norm(modes[:, i]) < 1e-12]
            what = f" (e.g. {', '.join(free)})" if free else ""
            raise ProblemError(
                f"the body is not constrained against rigid motion: {need - rank} of {need} rigid modes "
                f"are free{what}; prescribe more displacement components (fixed dofs)")

    # ------------------------------------------------------------------ sizes
    @property
    def n_dofs(self) -> int:
        return self.mesh.n_dofs

    @property
    def free_mask(self) -> np.ndarray:
        m = np.ones(self.n_dofs, bool)
        m[self.fixed] = False
        return m

    # ------------------------------------------------------------------ parameters
    def params(self, E=1.0, nu=0.3, thickness=1.0, u_D=0.0, f=0.0, traction=0.0, X=None, **extra) -> dict:
        """A full parameter pytree with every entry broadcast to its shape.

        Returns a dict of float64 arrays: ``E``, ``nu``, ``thickness`` and any material extras
        ``(n_cells,)``; ``X`` ``(n_nodes, dim)``; ``u_D`` ``(n_fixed,)``; ``f`` ``(n_dofs,)`` nodal
        point forces; ``traction`` ``(n_traction_facets, dim)``.
        """
        nc, dim = self.mesh.n_cells, self.mesh.dim
        _check_nu(nu, self)
        cellwise = {"E": E, "nu": nu, "thickness": thickness if dim == 2 else 1.0}
        for q in self.material.extra:
            cellwise[q.name] = extra.pop(q.name, q.default)
        if extra:
            raise ProblemError(f"unknown parameters {sorted(extra)} for the {self.material.name} law")
        p = {k: _full(v, (nc,)) for k, v in cellwise.items()}
        X = self.mesh.nodes if X is None else X
        p["X"] = _full(X, np.shape(X))
        p["u_D"] = _full(u_D, (len(self.fixed),))
        p["f"] = _full(f, (self.n_dofs,))
        p["traction"] = _full(traction, (len(self.traction_facets), dim))
        return p

    def prescribe(self, displacement) -> np.ndarray:
        """``u_D`` from a nodal displacement array ``(n_nodes, dim)`` or a callable ``x (n, dim) -> u (n, dim)``."""
        U = displacement(self.mesh.nodes) if callable(displacement) else np.asarray(displacement)
        return np.asarray(U, np.float64).reshape(-1)[self.fixed]
