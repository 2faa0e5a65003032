"""Taylor series of an equilibrium along a path in its parameters (the asymptotic-numerical method).

Given a converged equilibrium ``u0`` of the parameters ``theta`` and a path of parameters
``theta(t) = theta + sum_k c_k t^k`` (moduli, Poisson's ratio, thickness, reference coordinates;
the prescribed displacements and loads stay fixed), the equilibrium along the path,
``u(t) = u0 + sum_k u_k t^k``, follows order by order from ``R(u(t), theta(t)) = 0``:

    K u_k = -[R(u0 + u_1 t + ... + u_{k-1} t^{k-1}, theta(t))]_k

with ``K`` the tangent at ``u0`` (one factorisation serves every order) and ``[.]_k`` the k-th
Taylor coefficient, computed by Taylor-mode differentiation (``jax.experimental.jet``) of the
residual. This is the asymptotic-numerical method of Cochelin, Damil and Potier-Ferry: no Newton
iteration beyond the one that found ``u0``. The series itself converges only up to the nearest
singularity of ``u(t)`` in the complex plane (for a region's modulus, a pole at a negative
modulus), so a caller who needs ``u`` farther away continues it by a Pade approximant
(:mod:`refine.optimize.pade`).

Under plane stress the out-of-plane stretch ``l`` of every quadrature point is an unknown of the
series too, with its own equation h(l, F) = d psi / d F33 = 0: at each order the residual's and
h's coefficients come from one Taylor evaluation with the new coefficients left at zero, ``l_k``
is eliminated point by point (the condensation that gives the plane-stress tangent), ``u_k`` is
solved with the condensed tangent, and then ``l_k = -([h]_k + h_F : F_k) / h_l``. The Taylor
evaluation sees only the energy's gradient, never an inner Newton loop, so it compiles small.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from jax.experimental import jet

from . import _config  # noqa: F401
from .assembly import deformation_gradients, shape_gradients
from .exceptions import ProblemError
from .kinematics import embed
from .newton import external_force

FIXED_KEYS = ("u_D", "f", "traction")


def _point_law(energy, kind: str):
    """``(F, l, p) -> (P, h)``: the in-plane first Piola stress at the stretch ``l`` and the
    out-of-plane stress h = d psi / d F33 (whose root is the plane-stress stretch); under the
    other kinematics ``l`` is unused and h = 0."""
    if kind == "plane-stress":
        def law(F, l, p):
            P3 = jax.grad(energy)(embed(F, l), p)
            return P3[:2, :2], P3[2, 2]
    elif kind == "plane-strain":
        def law(F, l, p):
            return jax.grad(energy)(embed(F, jnp.ones_like(l)), p)[:2, :2], 0.0 * l
    else:
        def law(F, l, p):
            return jax.grad(energy)(F, p), 0.0 * l
    return law


def _per_point(fn, F, L, p):
    """``fn(F, l, p)`` at every quadrature point; ``p`` holds per-cell scalars."""
    return jax.vmap(lambda Fc, Lc, pc: jax.vmap(lambda Fq, lq: fn(Fq, lq, pc))(Fc, Lc))(F, L, p)


def _series_function(solver, keys: tuple, order: int):
    """Compiled ``(u0, theta, path) -> (coefficients (order, n_dofs), relative residual at u0)``,
    cached on the solver per (keys, order): changing only values never recompiles."""
    cache = solver.__dict__.setdefault("_series_functions", {})
    fn = cache.get((keys, order))
    if fn is not None:
        return fn
    arrays, asm = solver.arrays, solver.assembler
    el, dim, n = asm.el, solver.problem.mesh.dim, solver.problem.n_dofs
    cells, edofs, free = arrays["cells"], arrays["edofs"].ravel(), arrays["free"]
    law = _point_law(solver.problem.material.energy, solver.problem.kinematics)
    stretch = solver.problem.kinematics == "plane-stress"

    def assemble(Re):
        return jnp.zeros(n, Re.dtype).at[edofs].add(Re.reshape(-1))

    def run(u0, theta, path):
        p0, X0, t0 = solver._split(theta)
        _, F0, L0 = asm._forces(u0.reshape(-1, dim), X0, p0, t0, cells)  # converged stretches
        if not stretch:
            L0 = jnp.ones(F0.shape[:2], u0.dtype)
        dNdX0, dV0 = shape_gradients(X0, cells, el)
        w0 = dV0 * t0[:, None]
        vals = solver._constrained(solver.tangent_values(u0, theta))

        def forces(u, L, *values):
            th = {**theta, **dict(zip(keys, values))}
            p, X, t = solver._split(th)
            dNdX, dV = shape_gradients(X, cells, el)
            F = deformation_gradients(u.reshape(-1, dim), cells, dNdX)
            P, h = _per_point(law, F, L, p)
            Re = jnp.einsum("cqiK,cqaK,cq->cai", P, dNdX, dV * t[:, None])
            return assemble(Re) - external_force(th, th, arrays, solver._facet_element, n), h

        R0, h0 = forces(u0, L0, *(theta[k] for k in keys))
        scale = jnp.maximum(jnp.linalg.norm(R0 * (1.0 - free)), jnp.linalg.norm(
            external_force(theta, theta, arrays, solver._facet_element, n) * free))
        rel = jnp.linalg.norm(R0 * free) / jnp.maximum(scale, 1e-300)
        if stretch:
            # d/dl and d/dF of (P, h) at the base state: the stretch's elimination at every order
            (P_l, h_l), h_F = _per_point(
                lambda F, l, p: (jax.jacfwd(law, 1)(F, l, p), jax.jacfwd(law, 0)(F, l, p)[1]), F0, L0, p0)
            rel = jnp.maximum(rel, jnp.max(jnp.abs(h0)) / jnp.maximum(jnp.max(jnp.abs(p0["E"])), 1e-300))
        primals = (u0, L0, *(theta[k] for k in keys))

        def body(k, carry):
            U, L = carry
            series = ([U[j] for j in range(order)], [L[j] for j in range(order)],
                      *([path[key][j] for j in range(order)] for key in keys))
            _, (R_out, h_out) = jet.jet(forces, primals, series, factorial_scaled=False)
            Rk = jnp.stack(R_out)[k]
            if stretch:
                hk = jnp.stack(h_out)[k]
                dl = -hk / h_l  # the stretch's share with F_k = 0, folded into the residual
                Rk = Rk + assemble(jnp.einsum("cqiK,cq,cqaK,cq->cai", P_l, dl, dNdX0, w0))
            uk = -solver._lin(vals, Rk * free, arrays)
            U = U.at[k].set(uk)
            if stretch:
                Fk = jnp.einsum("cki,cqkj->cqij", uk.reshape(-1, dim)[cells], dNdX0)
                L = L.at[k].set(dl - jnp.einsum("cqij,cqij->cq", h_F, Fk) / h_l)
            return U, L

        zeros = (jnp.zeros((order, n), u0.dtype), jnp.zeros((order,) + L0.shape, u0.dtype))
        U, _ = jax.lax.fori_loop(0, order, body, zeros)
        return U, rel

    fn = cache[(keys, order)] = jax.jit(run)
    return fn


def equilibrium_series(solver, u0, theta: dict, path: dict, order: int, tol: float = 1e-6) -> jax.Array:
    """Taylor coefficients of the equilibrium along a path of parameters.

    Args:
        solver: the :class:`~jaxfem.solver.Solver`.
        u0: a converged equilibrium of ``theta``, ``(n_nodes, dim)`` or ``(n_dofs,)``.
        theta: its parameters (:meth:`~jaxfem.solver.Solver.params`).
        path: ``key -> (order, *shape)``: the Taylor coefficients of orders 1..order of each
            parameter that moves along the path (``theta[key] + sum_k path[key][k-1] t^k``);
            an affine path has zeros beyond the first. Prescribed displacements and loads
            (``u_D``, ``f``, ``traction``) cannot move.
        order: number of coefficients.
        tol: largest relative free residual accepted at ``u0``: the series of a state that is not
            an equilibrium is meaningless.
    Returns:
        ``(order, n_nodes, dim)``: ``u_1 ... u_order`` with ``u(t) = u0 + sum_k u_k t^k``
        (zero on constrained dofs).

    Costs one factorisation of the tangent at ``u0`` and ``order`` back-substitutions and Taylor
    evaluations of the residual; compiled once per solver, path keys and order.
    """
    if int(order) != order or order < 1:
        raise ProblemError(f"equilibrium_series: order must be a positive integer, not {order!r}")
    bad = [k for k in path if k in FIXED_KEYS or k not in theta]
    if bad:
        raise ProblemError(f"equilibrium_series: the path cannot move {bad}: it moves parameters of theta "
                         f"(not the prescribed displacements or loads {FIXED_KEYS})")
    keys = tuple(sorted(path))
    coeffs = {}
    for k in keys:
        shape = np.shape(theta[k])
        c = jnp.asarray(path[k], jnp.float64)
        if c.shape != (order, *shape):
            raise ProblemError(f"equilibrium_series: path[{k!r}] has shape {c.shape}, expected {(order, *shape)} "
                             f"(orders 1..{order} of theta[{k!r}], shape {shape})")
        coeffs[k] = c
    u0 = jnp.asarray(u0, jnp.float64).reshape(-1)
    U, rel = _series_function(solver, keys, int(order))(u0, theta, coeffs)
    rel = float(rel)
    if not rel <= tol:
        raise ProblemError(f"equilibrium_series: u0 is not an equilibrium of theta (relative free residual "
                         f"{rel:.3g} > {tol:g}); solve first")
    if not bool(jnp.all(jnp.isfinite(U))):
        raise ProblemError("equilibrium_series: the series is not finite (is the tangent at u0 singular?)")
    return U.reshape(order, -1, solver.problem.mesh.dim)
