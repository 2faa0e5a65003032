"""The solver: one jitted nonlinear solve per problem, differentiable through its equilibrium.

``Solver(problem)`` computes the sparsity pattern once and compiles once. Then

- :meth:`Solver.solve` runs Newton with load stepping and returns a :class:`Solution`, raising
  :class:`~jaxfem.exceptions.SolverError` (with the failing load step and the reason) on failure;
- :meth:`Solver.displacement` is the same solve as a differentiable function ``theta -> u``.

Derivatives of the converged equilibrium u*(theta) come from the implicit function theorem,
K du = -dR/dtheta dtheta: a ``custom_jvp`` whose tangent is one linear solve with the tangent
matrix at u*, written with ``lax.custom_linear_solve`` so that JAX can transpose it. Forward
mode (``jax.jvp``, ``jax.jacfwd``) costs one solve per direction; reverse mode (``jax.grad``) one
adjoint solve in all; Hessian-vector products work as well. Newton iterations and load steps are
never unrolled: for a hyperelastic (path-independent) material the equilibrium depends only on the
final loads, so the load path does not enter the derivative.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from . import _config  # noqa: F401
from .assembly import Assembler, make_pattern, matvec
from .exceptions import SolverError
from .kinematics import reduce
from .linsolve import make_linear_solver
from .newton import REASONS, NewtonOptions, external_force, newton_solve
from .problem import LOAD_KEYS, Problem


@dataclass(frozen=True, eq=False)
class Solution:
    """A converged equilibrium.

    Attributes:
        u: nodal displacements ``(n_nodes, dim)``.
        theta: the parameters it was solved for.
        info: counters of the solve (load steps, Newton iterations, cutbacks, residual log).
    """

    u: jax.Array
    theta: dict
    info: dict
    solver: "Solver"

    @property
    def problem(self) -> Problem:
        return self.solver.problem

    def newton_log(self) -> list[tuple[int, float]]:
        """(load step, relative free residual) after every Newton correction, in order."""
        res, step = np.asarray(self.info["residual_log"]), np.asarray(self.info["log_step"])
        keep = np.isfinite(res) & (step >= 0)  # unused slots are NaN with step -1
        return list(zip(step[keep].tolist(), res[keep].tolist()))


class Solver:
    """Nonlinear static solver for one :class:`Problem` (pattern and compilation done once).

    Args:
        problem: the problem.
        linear_solver: ``"auto"`` (default) or a name of :data:`jaxfem.linsolve.SOLVERS` that is
            installed (:func:`jaxfem.linsolve.available`).
        options: :class:`~jaxfem.newton.NewtonOptions`.
    """

    def __init__(self, problem: Problem, linear_solver: str = "auto", options: NewtonOptions | None = None):
        self.problem = problem
        self.options = options or NewtonOptions()
        mesh = problem.mesh
        self.pattern = pat = make_pattern(mesh)
        self.law = reduce(problem.material.energy, problem.kinematics)
        self.assembler = Assembler(mesh.element, self.law)
        free = problem.free_mask
        keep = free[pat.rows] & free[pat.cols]
        diag_fixed = np.zeros(pat.nnz)
        diag_fixed[pat.diag[~free]] = 1.0
        self.arrays = {
            "cells": jnp.asarray(mesh.cells, jnp.int32), "edofs": jnp.asarray(pat.edofs),
            "slots": jnp.asarray(pat.slots), "rows": jnp.asarray(pat.rows), "cols": jnp.asarray(pat.cols),
            "diag": jnp.asarray(pat.diag), "fixed": jnp.asarray(problem.fixed, jnp.int32),
            "free": jnp.asarray(free, jnp.float64), "keep": jnp.asarray(keep, jnp.float64),
            "diag_fixed": jnp.asarray(diag_fixed), "tfacets": jnp.asarray(problem.traction_facets, jnp.int32),
        }
        self.linear_solver, self._lin = make_linear_solver(linear_solver, pat, mesh.dim)
        self._facet_element = mesh.el.facet
        self._newton = jax.jit(partial(
            newton_solve, asm=self.assembler, lin=self._lin, nnz=pat.nnz, opts=self.options,
            facet_element=self._facet_element, finite=problem.material.finite))
        self._equilibrium = self._make_equilibrium()
        # compiled once: an eager jax.grad would otherwise run the implicit rule op by op (~1 s)
        self._displacement = jax.jit(self._equilibrium)

    # ------------------------------------------------------------------ parameters
    def params(self, **kw) -> dict:
        """Shortcut for :meth:`Problem.params`."""
        return self.problem.params(**kw)

    def _split(self, theta):
        p = {k: theta[k] for k in theta if k not in ("X", "thickness", "u_D", "f", "traction")}
        return p, theta["X"], theta["thickness"]

    # ------------------------------------------------------------------ residual and tangent
    def residual(self, u, theta):
        """Out-of-balance force R_int(u) - f_ext, ``(n_dofs,)`` (on fixed dofs: minus the reactions' opposite)."""
        p, X, t = self._split(theta)
        dim = X.shape[1]
        Rint = self.assembler.residual(u.reshape(-1, dim), X, p, t, self.arrays)
        return Rint - external_force(theta, theta, self.arrays, self._facet_element, self.problem.n_dofs)

    def tangent_values(self, u, theta):
        """Tangent matrix values on the pattern, ``(nnz,)`` (unconstrained)."""
        p, X, t = self._split(theta)
        _, vals, _ = self.assembler.residual_and_tangent(u.reshape(-1, X.shape[1]), X, p, t, self.arrays,
                                                      self.pattern.nnz)
        return vals

    def _constrained(self, vals):
        return vals * self.arrays["keep"] + self.arrays["diag_fixed"]

    # ------------------------------------------------------------------ the equilibrium map
    def _make_equilibrium(self):
        """The differentiable map theta -> u: Newton (not differentiated) for the value, the
        implicit function theorem for every derivative. Newton's last pass evaluated the tangent
        at the converged state; the derivative solves with it (``tangent_at``: those values, and
        for higher derivatives the derivative of the tangent, traced only when asked for)."""
        arrays = self.arrays

        @jax.custom_jvp
        def tangent_at(u, theta, vals):
            return vals

        @tangent_at.defjvp
        def tangent_at_jvp(primals, tangents):
            u, theta, vals = primals
            du, dtheta, _ = tangents
            # the primal through the rule again: a derivative of this one (a third derivative of
            # u) must see the tangent matrix move too, not the constant values Newton left
            return tangent_at(u, theta, vals), jax.jvp(self.tangent_values, (u, theta), (du, dtheta))[1]

        @jax.custom_jvp
        def implicit(theta, u, vals):
            return u

        @implicit.defjvp
        def implicit_jvp(primals, tangents):
            theta, u, vals = primals
            dtheta = tangents[0]
            u = implicit(theta, u, vals)  # the nested derivatives of u come through this rule again
            free, fixed = arrays["free"], arrays["fixed"]

            def free_residual(th):
                uu = u.at[fixed].set(th["u_D"], unique_indices=True)  # prescribed values enter through the constrained dofs
                return self.residual(uu, th) * free

            _, dG = jax.jvp(free_residual, (theta,), (dtheta,))
            du_D = dtheta["u_D"]
            rhs = -dG + jnp.zeros_like(u).at[fixed].set(du_D, unique_indices=True)
            M = self._constrained(tangent_at(u, theta, vals))
            mv = lambda x: matvec(M, arrays["rows"], arrays["cols"], x)  # noqa: E731
            du = jax.lax.custom_linear_solve(mv, rhs, lambda _, b: self._lin(jax.lax.stop_gradient(M), b, arrays),
                                             symmetric=True)
            return u, du

        def equilibrium(theta, u0, loads0):
            u, _, vals = self._newton(jax.lax.stop_gradient(theta), u0, loads0, arrays)
            return implicit(theta, u, vals)

        return equilibrium

    def _start(self, theta, start):
        n = self.problem.n_dofs
        if start is None:  # host zeros: no device dispatch per call
            zeros = {k: np.zeros(np.shape(theta[k])) for k in LOAD_KEYS}
            return np.zeros(n), zeros
        u0, loads0 = start
        return jnp.asarray(u0).reshape(n), {k: jnp.asarray(loads0[k]) for k in LOAD_KEYS}

    def displacement(self, theta, start=None):
        """Differentiable equilibrium displacements ``(n_nodes, dim)`` for the parameters ``theta``.

        Args:
            theta: parameter pytree (:meth:`params`).
            start: optional ``(u0, loads0)``: an equilibrium ``u0 (n_dofs,)`` of the loads ``loads0``
                (a dict with ``u_D``, ``f``, ``traction``) to continue from; it is not differentiated.
        Returns NaN where the solve failed (use :meth:`solve` for the error message).
        """
        u0, loads0 = self._start(theta, start)
        u0, loads0 = jax.lax.stop_gradient((u0, loads0))
        return self._displacement(theta, u0, loads0).reshape(-1, self.problem.mesh.dim)

    def solve(self, theta, start=None) -> Solution:
        """Solve and return a :class:`Solution`; raise :class:`SolverError` if Newton fails."""
        u0, loads0 = self._start(theta, start)
        u, info, _ = self._newton(theta, u0, loads0, self.arrays)
        info = jax.device_get(info)  # one transfer for all counters
        status = int(info["status"])
        if status != 0:
            step, s = int(info["fail_step"]), float(info["fail_load_factor"])
            why = {"no-convergence": "Newton did not converge (it stopped reducing the residual, or "
                                     "reached the iteration limit) even after cutting the load increment back",
                   "inverted-element": "an element inverted (det F <= 0) and cutting the load step back "
                                       "did not avoid it",
                   "singular-tangent": "the tangent matrix is singular (is the body unconstrained, or "
                                       "has the material lost stability?)",
                   "nan": "the residual became NaN (check the parameters for non-physical values)"}[REASONS[status]]
            raise SolverError(
                f"nonlinear solve failed at load step {step + 1} (from load factor {s:.4g} of 1, after "
                f"{int(info['cutbacks'])} cutbacks): {why}. Try smaller load increments "
                "(NewtonOptions.initial_step), more iterations, or check the boundary data.",
                step=step, load_factor=s, reason=REASONS[status])
        return Solution(u.reshape(-1, self.problem.mesh.dim), theta, {k: np.asarray(v) for k, v in info.items()},
                        self)

    def reactions(self, u, theta, nodes=None):
        """Reaction forces: the total force ``(dim,)`` that the constraints exert on ``nodes``
        (all fixed nodes by default)."""
        R = self.residual(jnp.asarray(u).reshape(-1), theta).reshape(-1, self.problem.mesh.dim)
        if nodes is None:
            nodes = np.unique(self.problem.fixed // self.problem.mesh.dim)
        return R[jnp.asarray(nodes)].sum(axis=0)

