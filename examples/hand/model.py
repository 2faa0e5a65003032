"""The hand as a boundary-value problem: soft tissue (nearly incompressible neo-Hookean, ``tet10``)
moved by its bones, the forearm's cut held; an optional scar as a stiffer region of soft tissue.

The bones are kinematic constraints: their nodes get the displacements of their rigid motions
(:func:`~examples.hand.kinematics.bone_displacements`) as Dirichlet values, so the bone cells carry
no strain. With ``Tissues(rigid_bones=False)`` only the middle third of each bone (along its
longest side) is driven and the rest deforms as bone (17 MPa, nu 0.31 by default). One
:class:`~jaxfem.Solver` serves every motion and every scar: the prescribed dofs are always all
the driven nodes (a joint at rest drives its bone by zero), and a scar changes only the per-cell
modulus, so nothing recompiles.

Units: mm, MPa (N/mm^2), radians.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax.numpy as jnp
import numpy as np

from jaxfem.exceptions import MeshError, ProblemError
from jaxfem.newton import NewtonOptions
from jaxfem.problem import Problem, dofs
from jaxfem.shapes import Ellipse
from jaxfem.solver import Solution, Solver
from .kinematics import bone_displacements
from .voxels import Hand


@dataclass(frozen=True)
class Tissues:
    """Material data (MPa): soft tissue (skin E 10-100 kPa, nu 0.49 in the paper), bone (17 MPa,
    nu 0.31) where bones deform, and whether bones are rigid (every bone node driven)."""

    E_soft: float = 0.05
    nu_soft: float = 0.49
    E_bone: float = 17.0
    nu_bone: float = 0.31
    rigid_bones: bool = True

    def __post_init__(self):
        for what, nu in (("soft tissue", self.nu_soft), ("bone", self.nu_bone)):
            if not -1.0 < nu < 0.5:
                raise ProblemError(f"the {what}'s Poisson's ratio must lie in (-1, 0.5), got {nu}: nu = 0.5 is "
                                   "incompressible, which a displacement formulation cannot represent; use "
                                   "nu <= 0.499 (soft tissue: 0.49)")
        if not (self.E_soft > 0 and self.E_bone > 0):
            raise ProblemError(f"moduli must be positive (MPa), got E_soft={self.E_soft}, E_bone={self.E_bone}")


@dataclass(frozen=True)
class Scar:
    """A scar: the soft tissue under ``outline`` (an ellipse in the (x, y) plane, mm) down to
    ``depth`` mm from the palm-side skin (-z), ``ratio`` times as stiff as the soft tissue (the
    paper's relative elasticity)."""

    outline: Ellipse
    depth: float
    ratio: float

    def __post_init__(self):
        if not (self.depth > 0 and self.ratio > 0):
            raise ProblemError(f"a scar needs a positive depth (mm) and ratio, got depth={self.depth}, "
                               f"ratio={self.ratio}")


def scar_cells(hand: Hand, scar: Scar) -> np.ndarray:
    """Whether each cell is scar, ``(n_cells,)``: soft-tissue cells whose centroid lies under the
    outline and within ``depth`` of the palm-side skin there (the lowest skin node under it).

    Raises:
        MeshError: the outline covers no skin, or no cell's centroid is that shallow (make the
            mesh finer or the scar deeper).
    """
    X = hand.mesh.nodes
    skin = np.unique(hand.skin_facets)
    under = skin[scar.outline.contains(X[skin, :2])]
    if under.size == 0:
        raise MeshError(f"the scar {scar.outline} covers no skin node of the hand; move it onto the hand")
    c = hand.mesh.centroids()
    cells = scar.outline.contains(c[:, :2]) & (c[:, 2] <= X[under, 2].min() + scar.depth) & ~hand.bone_cells
    if not cells.any():
        raise MeshError(f"no element's centre lies within {scar.depth} mm of the skin under the scar at "
                        f"h = {hand.h:g} mm; make the scar deeper or the mesh finer")
    return cells


class HandModel:
    """A hand ready to move: its :class:`~jaxfem.Problem` and compiled :class:`~jaxfem.Solver`.

    Args:
        hand: the meshed hand (:func:`~examples.hand.hand_mesh`).
        tissues: material data.
        linear_solver: as for :class:`~jaxfem.Solver`.
        options: as for :class:`~jaxfem.Solver`.
    """

    def __init__(self, hand: Hand, tissues: Tissues = Tissues(), linear_solver: str = "auto",
                 options: NewtonOptions | None = None):
        self.hand, self.tissues = hand, tissues
        driven = [self._driven(name) for name in hand.bone_nodes]
        self.driven = np.unique(np.concatenate([hand.held_nodes, *driven]))
        self.problem = Problem(hand.mesh, "neo-hookean", "solid", fixed=dofs(hand.mesh, self.driven))
        self.solver = Solver(self.problem, linear_solver, options)

    def _driven(self, name):
        nodes = self.hand.bone_nodes[name]
        if self.tissues.rigid_bones:
            return nodes
        bone = next(b for b in self.hand.body.bones if b.name == name)
        lo, hi = np.asarray(bone.box.lo), np.asarray(bone.box.hi)
        a = int(np.argmax(hi - lo))
        s = (self.hand.mesh.nodes[nodes, a] - lo[a]) / (hi[a] - lo[a])
        mid = nodes[(s >= 1 / 3) & (s <= 2 / 3)]
        if mid.size == 0:
            raise MeshError(f"bone {name!r} has no node in the middle third of its length at h = {self.hand.h:g} "
                            "mm to drive it by; make the mesh finer or the bones rigid")
        return mid

    def moduli(self, scar: Scar | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Young's modulus (MPa) and Poisson's ratio per cell, ``(n_cells,)`` each."""
        t, bone = self.tissues, self.hand.bone_cells
        E = np.where(bone, t.E_bone, t.E_soft)
        nu = np.where(bone, t.nu_bone, t.nu_soft)
        if scar is not None:
            E = np.where(scar_cells(self.hand, scar), scar.ratio * t.E_soft, E)
        return E, nu

    def params(self, angles: dict, scar: Scar | None = None) -> dict:
        """The parameter pytree for the joint ``angles`` ``{name: radians}`` and an optional scar."""
        E, nu = self.moduli(scar)
        u_D = self.problem.prescribe(bone_displacements(self.hand, angles))
        return self.problem.params(E=E, nu=nu, u_D=u_D)

    def drive(self, angles: dict):
        """The kinematic Dirichlet data ``u_D (n_fixed,)`` (mm) for ``angles`` ``{name: radians}`` as
        a JAX array, differentiable in the angles: ``{**model.params({}), "u_D": model.drive(a)}``
        is a parameter pytree whose solve (:meth:`jaxfem.Solver.displacement`) has exact derivatives
        in the joint angles."""
        U = bone_displacements(self.hand, angles, jnp)
        return U.reshape(-1)[jnp.asarray(self.problem.fixed)]

    def solve(self, angles: dict, scar: Scar | None = None, start=None) -> Solution:
        """The equilibrium at ``angles`` (radians); ``start`` as for :meth:`jaxfem.Solver.solve`.
        Raises :class:`~jaxfem.SolverError` where Newton fails at every cut-back."""
        return self.solver.solve(self.params(angles, scar), start)
