"""The solver: one jitted nonlinear solve per problem, differentiable through its equilibrium.

``Solver(problem)`` computes the sparsity pattern once; its compiled programs are those of every
problem of its kind (:mod:`jaxfem.program`), its mesh arrays their arguments, padded to bucket
sizes (:mod:`jaxfem.padding`), so a solver of another mesh of about the same size compiles
nothing. Then

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
from types import SimpleNamespace

import jax
import jax.numpy as jnp
import numpy as np

from . import _config  # noqa: F401
from . import padding
from .assembly import make_pattern
from .exceptions import SolverError
from .linsolve import HostSolver, make_linear_solver
from .linsolve._base import _host_solve, csr
from .newton import REASONS, NewtonOptions
from .newton_host import host_newton, loop_on_host
from .problem import LOAD_KEYS, Problem
from .program import program


def _traced(tree) -> bool:
    return any(isinstance(x, jax.core.Tracer) for x in jax.tree.leaves(tree))


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
    """Nonlinear static solver for one :class:`Problem` (pattern once; its programs are shared).

    The compiled programs (:mod:`jaxfem.program`) belong to the kind of problem (element, law,
    kinematics, linear solver kind, options); this solver's mesh arrays are their arguments,
    padded to bucket sizes (:mod:`jaxfem.padding`), so a second solver of a mesh of about the same
    size compiles nothing.

    Args:
        problem: the problem.
        linear_solver: ``"auto"`` (default) or a name of :data:`jaxfem.linsolve.SOLVERS` that is
            installed (:func:`jaxfem.linsolve.available`).
        options: :class:`~jaxfem.newton.NewtonOptions`.
        headroom: pad as for a mesh this many times larger (every count), so that larger meshes
            of its kind solved later (e.g. a diagnosis's hypotheses, whose meshes follow shapes)
            reuse this solver's programs (:meth:`jaxfem.program.Program.sizes_for`); 1: its own
            bucket.
    """

    def __init__(self, problem: Problem, linear_solver: str = "auto", options: NewtonOptions | None = None,
                 headroom: float = 1.0):
        self.problem = problem
        self.options = options or NewtonOptions()
        mesh = problem.mesh
        self.pattern = pat = make_pattern(mesh)
        free = problem.free_mask
        keep = free[pat.rows] & free[pat.cols]
        diag_fixed = np.zeros(pat.nnz)
        diag_fixed[pat.diag[~free]] = 1.0
        # the real sizes, for callers that assemble themselves (series, post-processing)
        # (device_put, not jnp.asarray: that compiles a small program per array shape)
        self._keep_host, self._diag_fixed_host = keep.astype(np.float64), diag_fixed  # for host-side tangents
        self.arrays = jax.device_put({
            "cells": mesh.cells.astype(np.int32), "edofs": pat.edofs, "slots": pat.slots, "rows": pat.rows,
            "cols": pat.cols, "diag": pat.diag, "fixed": problem.fixed.astype(np.int32),
            "free": free.astype(np.float64), "keep": keep.astype(np.float64), "diag_fixed": diag_fixed,
            "tfacets": problem.traction_facets.astype(np.int32)})
        self.linear_solver, self._lin = make_linear_solver(linear_solver, pat, mesh.dim)
        self._facet_element = mesh.el.facet
        self.program = program(mesh.element, problem.material, problem.kinematics, self._lin, self.options,
                               self._facet_element)
        self.law, self.assembler = self.program.asm.law, self.program.asm
        self.sizes = padding.sizes(mesh.n_cells, mesh.n_nodes, mesh.dim, pat.nnz, len(problem.fixed),
                                   pad=self._lin.pads, n_facets=len(problem.traction_facets))
        if self._lin.pads:  # room for larger meshes, or a larger padding the program was given, where one holds this mesh
            self.sizes = self.program.sizes_for(padding.with_headroom(self.sizes, headroom))
        # the traction facets padded too (with a facet mask), so that another count of loaded
        # facets (a hole cut through a loaded face, a remesh) compiles nothing
        padded = padding.padded_arrays(self.sizes, mesh.cells, pat, problem.fixed, free, problem.traction_facets)
        if isinstance(self._lin, HostSolver):
            padded["host"] = np.int32(self._lin.host_id)
        self.padded_arrays = jax.device_put(padded)
        self._host_of = (None, None)  # (padded arrays, their host copies: _host)
        self.on_host = loop_on_host()
        prog = self.program
        self._kernels = SimpleNamespace(evaluate=prog.evaluate, external=prog.external, min_det=prog.min_det,
                                        n_qp=prog.n_qp, solve=self._host_solve)

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
        return self.program.residual(jnp.asarray(u).reshape(-1), theta, self.arrays)

    def tangent_values(self, u, theta):
        """Tangent matrix values on the pattern, ``(nnz,)`` (unconstrained)."""
        return self.program.tangent_values(jnp.asarray(u).reshape(-1), theta, self.arrays)

    def _constrained(self, vals):
        return self.program.constrained(vals, self.arrays)

    # ------------------------------------------------------------------ the solves on the host
    @property
    def _host(self) -> dict:
        """What the loop on the host reads of :attr:`padded_arrays` (host numpy, copied once)."""
        arrays, host = self._host_of
        if arrays is not self.padded_arrays:
            host = {k: np.asarray(self.padded_arrays[k]) for k in ("rows", "cols", "fixed", "free", "keep", "diag_fixed")}
            host["n_cells"] = self.padded_arrays["cells"].shape[0]
            self._host_of = (self.padded_arrays, host)
        return host

    def _host_solve(self, K, rhs):
        """x with K x = rhs for the constrained padded matrix values ``K (nnz_p,)`` and ``rhs``
        ``(n_dofs_p,)`` or ``(n_dofs_p, k)``, host numpy."""
        if isinstance(self._lin, HostSolver):
            return _host_solve(self._lin.host_id, K, rhs)
        run = self.program.linear if np.ndim(rhs) == 1 else self.program.linear_many
        return np.asarray(run(K, rhs, self.padded_arrays))

    def _newton(self, theta_p, u0, loads0):
        """Newton on the padded problem: ``(u, info, vals)`` (:func:`jaxfem.newton.newton_solve`)."""
        if self.on_host:
            return host_newton(self._kernels, theta_p, u0, loads0, self.padded_arrays, self._host, self.options,
                               self.program.finite)
        with self.program.lock:  # wait inside the lock: a later np.asarray would wait holding the GIL
            return jax.block_until_ready(self.program.newton(theta_p, u0, loads0, self.padded_arrays))

    # ------------------------------------------------------------------ padding
    def _pad(self, theta, u0, loads0):
        s = self.sizes
        theta = padding.pad_theta(theta, s)
        xp = jnp if isinstance(u0, jax.core.Tracer) else np
        u0 = xp.pad(xp.asarray(u0, np.float64).reshape(-1), (0, s.n_dofs_p - s.n_dofs))
        loads0 = padding.pad_theta(loads0, s, tangent=True)
        return theta, u0, loads0

    def _unpad(self, u):
        """The real dofs of padded displacements ``(..., n_dofs_p)`` as ``(..., n_nodes, dim)``."""
        dim = self.problem.mesh.dim
        if isinstance(u, jax.core.Tracer):
            return u[..., : self.sizes.n_dofs].reshape(u.shape[:-1] + (-1, dim))
        u = np.asarray(u)  # no device operation to compile per mesh size
        return jax.device_put(u[..., : self.sizes.n_dofs].reshape(u.shape[:-1] + (-1, dim)))

    def _start(self, theta, start):
        n = self.problem.n_dofs
        if start is None:  # host zeros: no device dispatch per call
            zeros = {k: np.zeros(np.shape(theta[k])) for k in LOAD_KEYS}
            return np.zeros(n), zeros
        u0, loads0 = start
        if not _traced(start):  # host arrays: no device operation to compile per mesh size
            return np.asarray(u0, np.float64).reshape(n), {k: np.asarray(loads0[k], np.float64) for k in LOAD_KEYS}
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
        if not _traced((theta, u0, loads0)):  # nothing to differentiate: Newton alone
            return self._unpad(self._newton(*self._pad(theta, u0, loads0))[0])
        u0, loads0 = jax.lax.stop_gradient((u0, loads0))
        theta, u0, loads0 = self._pad(theta, u0, loads0)
        return self._unpad(self.program.displacement(theta, u0, loads0, self.padded_arrays))

    def solve(self, theta, start=None) -> Solution:
        """Solve and return a :class:`Solution`; raise :class:`SolverError` if Newton fails."""
        u, info, _ = self._solve_padded(theta, start)
        u = self._unpad(u)
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
        return Solution(u, theta, {k: np.asarray(v) for k, v in info.items()},
                        self)

    def _solve_padded(self, theta, start):
        u0, loads0 = self._start(theta, start)
        return self._newton(*self._pad(theta, u0, loads0))

    def solve_with_tangents(self, theta, directions, start=None):
        """The equilibrium and its derivatives along ``k`` parameter directions, by the implicit
        function theorem at the converged state (one factorisation, one back-substitution per
        direction); no error is raised (NaN where the solve failed: :meth:`solve` says why).

        Args:
            theta: parameter pytree (:meth:`params`).
            directions: a pytree like ``theta`` with a leading axis ``k`` (zeros where a parameter
                does not move).
            start: as in :meth:`displacement`.
        Returns:
            ``(u (n_nodes, dim), du (k, n_nodes, dim), info)``.
        """
        u, info, vals = self._solve_padded(theta, start)
        return self._unpad(u), self.tangents_at((padding.pad_theta(theta, self.sizes), u, vals), directions), info

    def tangents_at(self, state, directions):
        """``du (k, n_nodes, dim)``: the equilibrium's derivatives along ``k`` parameter
        ``directions`` (as in :meth:`solve_with_tangents`) at the converged ``state`` of
        :meth:`solve_for_adjoint`, for a caller that solved already and asks for them later (or
        not at all: a fit's rejected steps)."""
        th, u, vals = state
        k = np.shape(jax.tree.leaves(directions)[0])[0]
        dirs = padding.pad_theta(padding.pad_batch(directions, k), self.sizes, tangent=True, axis=1)
        chunks = [jax.tree.map(lambda v: v[i: i + padding.BATCH], dirs) for i in range(0, k, padding.BATCH)]
        if self.on_host:  # the right-hand sides by a kernel, every direction a back-substitution here
            rhs = np.concatenate([np.asarray(self.program.tangent_rhs(th, u, d, self.padded_arrays)) for d in chunks])
            K = np.asarray(vals) * self._host["keep"] + self._host["diag_fixed"]
            return self._unpad(np.asarray(self._host_solve(K, rhs[:k].T)).T)
        with self.program.lock:
            du = [np.asarray(self.program.tangents(th, u, vals, d, self.padded_arrays)) for d in chunks]
        return self._unpad(np.concatenate(du)[:k])

    def solve_with_prescribed_tangents(self, theta, du_D, start=None):
        """The equilibrium and its derivatives along ``m`` directions of the prescribed values
        alone, ``du_D (m, n_fixed)`` (e.g. a measured drive's columns): as
        :meth:`solve_with_tangents` with every other parameter held, the same figures to
        round-off. Where the linear solver factorises on the host, the right-hand sides are the
        converged tangent's coupling of the free to the prescribed dofs (one sparse product on the
        host, ``K du = -K_fd du_D``) and every direction a back-substitution of one factorisation
        (in one call): no assembly per direction (the tangents program's ``jvp`` of the residual
        assembles the material's tangent once per direction; a drive of ~130 values a frame
        took ~16 batches of it per frame). Other solvers: :meth:`solve_with_tangents`.

        Returns:
            ``(u (n_nodes, dim), du (m, n_nodes, dim), info)``; NaN where the solve failed.
        """
        du_D = np.asarray(du_D, np.float64)
        m = du_D.shape[0]
        if not isinstance(self._lin, HostSolver):
            zero = {k: np.zeros((m,) + np.shape(v)) for k, v in theta.items() if k != "u_D"}
            return self.solve_with_tangents(theta, {**zero, "u_D": du_D}, start=start)
        u, info, vals = self._solve_padded(theta, start)
        n, nnz = self.problem.n_dofs, self.pattern.nnz
        v = np.asarray(vals)[:nnz]
        gap = np.zeros((n, m))
        gap[self.problem.fixed] = du_D.T
        free = self.problem.free_mask[:, None]
        rhs = np.where(free, -(csr(self.pattern, v) @ gap), gap)
        K = v * self._keep_host + self._diag_fixed_host  # the constrained matrix, as the programs solve it
        with self.program.lock:  # the host solver's factorisation is the programs' too: one user at a time
            du = np.asarray(self._lin._cache(K, rhs)).T if m else np.zeros((0, n))  # every direction in one call
        dim = self.problem.mesh.dim
        return self._unpad(u), jax.device_put(np.ascontiguousarray(du).reshape(m, -1, dim)), info

    def solve_for_adjoint(self, theta, start=None):
        """The equilibrium ``u (n_nodes, dim)`` (NaN where the solve failed; no error raised) and
        what :meth:`adjoint` needs to differentiate a function of it (the converged state)."""
        theta_p, u0, loads0 = self._pad(theta, *self._start(theta, start))
        u, _, vals = self._newton(theta_p, u0, loads0)
        return self._unpad(u), (theta_p, u, vals)

    def adjoint(self, state, g) -> dict:
        """The gradient with respect to the parameters (a pytree like ``theta``) of a function of
        the equilibrium whose gradient with respect to ``u`` is ``g (n_nodes, dim)``: one adjoint
        solve (the implicit function theorem's transpose) at the ``state`` of
        :meth:`solve_for_adjoint`."""
        theta_p, u, vals = state
        s = self.sizes
        g = np.pad(np.asarray(g, np.float64).reshape(-1), (0, s.n_dofs_p - s.n_dofs))
        if self.on_host:  # the adjoint solve here (the matrix is symmetric), its transpose by a kernel
            K = np.asarray(vals) * self._host["keep"] + self._host["diag_fixed"]
            w = self._host_solve(K, g)
            return padding.unpad_theta(jax.device_get(self.program.adjoint_rhs(theta_p, u, w, self.padded_arrays)), s)
        with self.program.lock:
            grad = jax.block_until_ready(self.program.adjoint(theta_p, u, vals, g, self.padded_arrays))
        return padding.unpad_theta(grad, s)

    def reactions(self, u, theta, nodes=None):
        """Reaction forces: the total force ``(dim,)`` that the constraints exert on ``nodes``
        (all fixed nodes by default)."""
        R = self.residual(jnp.asarray(u).reshape(-1), theta).reshape(-1, self.problem.mesh.dim)
        if nodes is None:
            nodes = np.unique(self.problem.fixed // self.problem.mesh.dim)
        return R[jnp.asarray(nodes)].sum(axis=0)

