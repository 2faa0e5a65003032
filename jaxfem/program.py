"""The compiled programs of the solve, shared by every :class:`~jaxfem.solver.Solver` of one kind.

A program is made for what the solve's code depends on: the element, the material law under its
kinematics, the linear solver's kind and the Newton options. The mesh (coordinates through the
parameters, connectivity, sparsity pattern, constraints, traction-loaded facets) comes as
arguments, padded to a few bucket sizes (:mod:`jaxfem.padding`), so the models of one diagnosis
(its hypotheses, remeshes and fits) compile each program once per bucket instead of once per mesh
(5-10 CPU s each, whatever the mesh size, when the mesh arrays were constants of the program).

Each program's pieces are pure functions of ``(theta, ..., arrays)``:

- :attr:`Program.newton`: Newton with load stepping (:func:`jaxfem.newton.newton_solve`);
- :attr:`Program.displacement`: the differentiable equilibrium ``theta -> u``: Newton for the
  value, the implicit function theorem for every derivative (a ``custom_jvp`` whose tangent is one
  linear solve with the tangent matrix at u*, through ``lax.custom_linear_solve`` so that JAX can
  transpose it: forward mode costs one solve per direction, reverse mode one adjoint solve);
- :attr:`Program.tangents`: the same tangents for a batch of parameter directions at a converged
  state, for a caller that solved already (a Jacobian by forward mode, one back-substitution per
  direction after one factorisation).

A mesh smaller than one the program has already been padded for reuses that larger padding
(:meth:`Program.sizes_for`, within :data:`REUSE` times its own cell count) instead of compiling
its own bucket: each compiled size costs its Newton, tangents and adjoint (several CPU seconds
each), while padding only adds cells that carry nothing (the host linear solvers factorise the
real matrix alone). In a diagnosis the chosen model's refit on a coarser mesh (about half the
cells) so runs on the refit's programs. The other way round, a solver made with ``headroom``
(:class:`~jaxfem.solver.Solver`) is padded as for a larger mesh, which larger meshes made later
then reuse (a diagnosis's search model and its hypotheses' meshes, which follow the shapes).
"""

from __future__ import annotations

import threading
from functools import lru_cache, partial

import jax
import jax.numpy as jnp

from . import padding
from .assembly import Assembler, matvec
from .executables import Kept
from .kinematics import reduce
from .newton import NewtonOptions, external_force, loads_at, newton_solve

#: a mesh reuses a padded size already compiled for where it has at most this many times its own
#: cells (its own bucket is up to 19 % above it); padding cells cost their share of the
#: assembly, which is small beside a compile of the solve (a mesh half the size of the last:
#: 2 to 2.4 times)
REUSE = 2.5

#: parameters that are not per-cell material values
NOT_MATERIAL = ("X", "thickness", "u_D", "f", "traction")


@lru_cache(maxsize=None)
def reduced_law(material, kinematics: str):
    """The material's energy under ``kinematics`` (one object per pair, so programs can be shared)."""
    return reduce(material.energy, kinematics)


def split(theta):
    """``(per-cell material parameters, X, thickness)`` of a parameter pytree."""
    return {k: theta[k] for k in theta if k not in NOT_MATERIAL}, theta["X"], theta["thickness"]


class Program:
    """The jitted pieces of the solve for one element, law, kinematics, linear solver kind and
    Newton options (see the module doc); made by :func:`program`, never directly."""

    def __init__(self, asm: Assembler, lin, opts: NewtonOptions, facet_element: str, finite: bool, depends=None):
        self.asm, self.lin, self.facet_element = asm, lin, facet_element
        #: what the programs compute besides the shapes (:func:`program`'s key; None: unknown, so
        #: the kernels are not kept on disk)
        self.depends = depends if depends is not None else object()
        # one call of a shared executable at a time, waited for with the GIL released: a thread
        # that waits inside XLA for a busy executable holds the GIL, which the running one's host
        # solver callback needs (a diagnosis's two workers hung so, all threads waiting)
        self.lock = threading.Lock()
        self._sizes: list = []  # the padded sizes solvers of this program were given, in order
        self._sizes_lock = threading.Lock()
        self._newton = partial(newton_solve, asm=asm, lin=lin, opts=opts, facet_element=facet_element,
                               finite=finite)
        self.newton = jax.jit(self._newton)
        self._implicit = self._make_implicit()
        self.displacement = jax.jit(self._equilibrium)
        self.tangents = jax.jit(self._tangents)
        self.adjoint = jax.jit(self._adjoint)
        # the kernels of the loop on the host (jaxfem.newton_host): nothing in them calls back into
        # Python (and, kept whole on disk, neither traced nor lowered in a later process: the key
        # is what the program was made for, :attr:`depends`)
        self.finite, self.n_qp = finite, asm.el.weights.shape[0]
        keep = lambda f, name: Kept(f, f"program.{name}", self.depends)  # noqa: E731
        self.evaluate = keep(self._evaluate, "evaluate")
        self.external = keep(self._external, "external")
        self.min_det = keep(self._min_det, "min_det")
        self.tangent_rhs = keep(self._tangent_rhs_batch, "tangent_rhs")
        self.adjoint_rhs = keep(self._adjoint_rhs, "adjoint_rhs")
        self.linear = jax.jit(lin)  # for a solver that runs in XLA (a host solver's is never called so)
        self.linear_many = jax.jit(jax.vmap(lin, in_axes=(None, 1, None), out_axes=1))

    def __stable_key__(self):
        """What :mod:`jaxfem.executables` keys a function that closes over this program by."""
        return self.depends

    def sizes_for(self, own: padding.Sizes, reuse: float = REUSE) -> padding.Sizes:
        """The padded sizes a new solver of real sizes ``own`` (padded to its own bucket) is given:
        the smallest padded sizes this program already gave that hold it (:func:`padding.fits`)
        with at most ``reuse`` times its cells, else the smallest such whose mesh padding holds it
        with the traction facets of its own bucket, else its own (either recorded). Which one a mesh is
        given depends on the solvers of this program made before it in the process; the solve
        does not (padding carries nothing; a diagnosis's figures were the same to every printed
        digit). A solver whose linear solver takes no padding does not ask."""
        with self._sizes_lock:
            near = [s for s in self._sizes if s.n_cells_p <= reuse * max(own.n_cells, 1)]
            held = [s for s in near if padding.fits(own, s)]
            if held:
                return padding.padded_to(own, min(held, key=_smallest))
            # where only the traction facets do not fit, keep the mesh's padding and give the facets
            # their own bucket: the solve compiles for the new facet count, the programs sized by the
            # mesh alone (the points' interpolation) do not
            mixed = [m for m in (padding.with_facets_of(s, own) for s in near) if padding.fits(own, m)]
            own = padding.padded_to(own, min(mixed, key=_smallest)) if mixed else own
            self._sizes.append(own)
            return own

    # ------------------------------------------------------------------ residual and tangent
    def residual(self, u, theta, arrays):
        """Out-of-balance force R_int(u) - f_ext, ``(n_dofs,)``."""
        p, X, t = split(theta)
        dim = X.shape[1]
        Rint = self.asm.residual(u.reshape(-1, dim), X, p, t, arrays)
        return Rint - external_force(theta, theta, arrays, self.facet_element, u.size)

    def tangent_values(self, u, theta, arrays):
        """Tangent matrix values on the pattern, ``(nnz,)`` (unconstrained)."""
        p, X, t = split(theta)
        return self.asm.residual_and_tangent(u.reshape(-1, X.shape[1]), X, p, t, arrays)[1]

    @staticmethod
    def constrained(vals, arrays):
        """The matrix with Dirichlet (and padding) rows and columns replaced by the identity."""
        return vals * arrays["keep"] + arrays["diag_fixed"]

    # ------------------------------------------------------------------ the equilibrium map
    def _make_implicit(self):
        """``implicit(theta, u, vals, arrays) -> u`` whose derivative is the implicit function
        theorem's. Newton's last pass evaluated the tangent at the converged state; the derivative
        solves with it (``tangent_at``: those values, and for higher derivatives the derivative of
        the tangent, traced only when asked for)."""

        @jax.custom_jvp
        def tangent_at(u, theta, vals, arrays):
            return vals

        @tangent_at.defjvp
        def tangent_at_jvp(primals, tangents):
            u, theta, vals, arrays = primals
            du, dtheta = tangents[:2]
            # the primal through the rule again: a derivative of this one (a third derivative of
            # u) must see the tangent matrix move too, not the constant values Newton left
            dvals = jax.jvp(lambda uu, th: self.tangent_values(uu, th, arrays), (u, theta), (du, dtheta))[1]
            return tangent_at(u, theta, vals, arrays), dvals

        @jax.custom_jvp
        def implicit(theta, u, vals, arrays):
            return u

        @implicit.defjvp
        def implicit_jvp(primals, tangents):
            theta, u, vals, arrays = primals
            dtheta = tangents[0]
            u = implicit(theta, u, vals, arrays)  # the nested derivatives of u come through this rule again
            M = self.constrained(tangent_at(u, theta, vals, arrays), arrays)
            return u, self._solve_tangent(theta, u, M, dtheta, arrays)

        return implicit

    def _tangent_rhs(self, theta, u, dtheta, arrays):
        """The right-hand side of :meth:`_solve_tangent`: -dG/dtheta dtheta on the free dofs and
        du_D on the prescribed ones (linear in ``dtheta``)."""
        free, fixed = arrays["free"], arrays["fixed"]

        def free_residual(th):
            uu = u.at[fixed].set(th["u_D"], unique_indices=True)  # prescribed values enter through the constrained dofs
            return self.residual(uu, th, arrays) * free

        _, dG = jax.jvp(free_residual, (theta,), (dtheta,))
        return -dG + jnp.zeros_like(u).at[fixed].set(dtheta["u_D"], unique_indices=True)

    def _tangent_rhs_batch(self, theta, u, dthetas, arrays):
        """:meth:`_tangent_rhs` for a batch of directions (a leading axis in ``dthetas``)."""
        return jax.vmap(self._tangent_rhs, in_axes=(None, None, 0, None))(theta, u, dthetas, arrays)

    def _adjoint_rhs(self, theta, u, w, arrays):
        """The parameters' cotangent (a pytree like ``theta``) of the adjoint solution ``w``: the
        transpose of :meth:`_tangent_rhs` applied to ``w``."""
        zero = jax.tree.map(jnp.zeros_like, theta)
        return jax.vjp(lambda d: self._tangent_rhs(theta, u, d, arrays), zero)[1](w)[0]

    def _solve_tangent(self, theta, u, M, dtheta, arrays):
        """du with K du = -dG/dtheta dtheta on the free dofs and du = du_D on the prescribed ones."""
        rhs = self._tangent_rhs(theta, u, dtheta, arrays)
        mv = lambda x: matvec(M, arrays["rows"], arrays["cols"], x)  # noqa: E731
        return jax.lax.custom_linear_solve(mv, rhs, lambda _, b: self.lin(jax.lax.stop_gradient(M), b, arrays),
                                           symmetric=True)

    # ------------------------------------------------------------------ the host loop's kernels
    def _evaluate(self, theta, u, lam, arrays):
        """``(R_int, vals, lam)``: internal forces, tangent values on the pattern and the
        material state at ``u`` (the state's iteration started from ``lam``)."""
        p, X, t = split(theta)
        return self.asm.residual_and_tangent(u.reshape(-1, X.shape[1]), X, p, t, arrays, arrays["rows"].shape[0], lam)

    def _external(self, theta, loads0, s, arrays):
        """The external force a fraction ``s`` of the way from ``loads0`` to ``theta``'s loads."""
        return external_force(theta, loads_at(theta, loads0, s), arrays, self.facet_element, theta["X"].size)

    def _min_det(self, theta, u, arrays):
        """The smallest det F at ``u``."""
        X = theta["X"]
        return self.asm.min_jacobian(u.reshape(-1, X.shape[1]), X, arrays["cells"], arrays.get("cell_mask"))

    def _equilibrium(self, theta, u0, loads0, arrays):
        u, _, vals = self._newton(jax.lax.stop_gradient(theta), u0, loads0, arrays)
        return self._implicit(theta, u, vals, arrays)

    def _tangents(self, theta, u, vals, dthetas, arrays):
        """``(k, n_dofs)``: du for each of the ``k`` directions ``dthetas`` (a pytree like
        ``theta`` with a leading axis k) at the converged ``u`` with tangent values ``vals``."""
        M = self.constrained(vals, arrays)
        return jax.vmap(lambda d: self._solve_tangent(theta, u, M, d, arrays))(dthetas)


    def _adjoint(self, theta, u, vals, g, arrays):
        """The parameters' cotangent (a pytree like ``theta``) of the cotangent ``g (n_dofs,)`` of
        the converged ``u``: one adjoint solve (the transpose of :meth:`_solve_tangent`)."""
        return jax.vjp(lambda th: self._implicit(th, u, vals, arrays), theta)[1](g)[0]


def _smallest(s: padding.Sizes) -> tuple:
    return s.n_cells_p, s.nnz_p, s.n_nodes_p, s.n_facets_p


_PROGRAMS: dict = {}


def program(element: str, material, kinematics: str, lin, opts: NewtonOptions, facet_element: str) -> Program:
    """The shared :class:`Program` for this element, law, kinematics, linear solver kind
    (:meth:`~jaxfem.linsolve.LinearSolver.program_key`) and options; made on first use."""
    key = (element, material, kinematics, lin.program_key(), opts, facet_element)
    if key not in _PROGRAMS:
        law = reduced_law(material, kinematics)
        _PROGRAMS[key] = Program(Assembler(element, law), lin.shared(), opts, facet_element, material.finite, key)
    return _PROGRAMS[key]
