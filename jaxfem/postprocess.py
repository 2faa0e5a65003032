"""Post-processing of an equilibrium: deformation gradients, strains, stresses, energy.

Every function takes the solver (for the mesh, element and material law), the displacements
``u (n_nodes, dim)`` and the parameters ``theta``, and returns per-cell values (the average over
the cell's quadrature points, weighted by volume), so that maps and VTU cell data come directly.
All are JAX functions (differentiable). 3x3 tensors include the out-of-plane direction in 2D.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from . import _config  # noqa: F401
from .assembly import _per_qp, deformation_gradients, shape_gradients
from ._small import det


def _cell_average(q, dV):
    """Volume-weighted mean over quadrature points: ``q (c, nq, ...)`` -> ``(c, ...)``."""
    w = dV / dV.sum(axis=1, keepdims=True)
    return jnp.einsum("cq,cq...->c...", w, q)


def _qp(solver, u, theta):
    p, X, _ = solver._split(theta)
    cells = solver.arrays["cells"]
    dNdX, dV = shape_gradients(X, cells, solver.assembler.el)
    F = deformation_gradients(jnp.asarray(u).reshape(X.shape), cells, dNdX)
    return F, p, dV


def deformation_gradient(solver, u, theta):
    """Full 3x3 deformation gradient per cell, ``(n_cells, 3, 3)`` (F33 from the kinematics in 2D)."""
    F, p, dV = _qp(solver, u, theta)
    return _cell_average(_per_qp(solver.law.full_F, F, p), dV)


def green_lagrange_strain(solver, u, theta):
    """Green-Lagrange strain E = (F^T F - I) / 2 per cell, ``(n_cells, 3, 3)`` (dimensionless)."""
    F, p, dV = _qp(solver, u, theta)
    F3 = _per_qp(solver.law.full_F, F, p)
    E = 0.5 * (jnp.einsum("cqki,cqkj->cqij", F3, F3) - jnp.eye(3))
    return _cell_average(E, dV)


def principal_strains(solver, u, theta):
    """In-plane (2D) or full (3D) principal Green-Lagrange strains per cell, descending,
    ``(n_cells, dim)``."""
    E = green_lagrange_strain(solver, u, theta)
    d = solver.problem.mesh.dim
    return jnp.linalg.eigvalsh(E[:, :d, :d])[:, ::-1]


def equivalent_strain(solver, u, theta):
    """Von Mises equivalent strain sqrt(2/3 dev(E):dev(E)) per cell, ``(n_cells,)``: one number
    that is large where the material is strongly deformed (the strain maps' default)."""
    E = green_lagrange_strain(solver, u, theta)
    dev = E - jnp.trace(E, axis1=1, axis2=2)[:, None, None] * jnp.eye(3) / 3.0
    return jnp.sqrt(2.0 / 3.0 * jnp.sum(dev * dev, axis=(1, 2)))


def first_piola_stress(solver, u, theta):
    """First Piola-Kirchhoff stress P = d psi / dF per cell, ``(n_cells, 3, 3)`` (stress units)."""
    F, p, dV = _qp(solver, u, theta)
    psi = solver.problem.material.energy
    P = _per_qp(lambda Fq, pc: jax.grad(psi)(solver.law.full_F(Fq, pc), pc), F, p)
    return _cell_average(P, dV)


def second_piola_stress(solver, u, theta):
    """Second Piola-Kirchhoff stress S = F^-1 P per cell, ``(n_cells, 3, 3)``."""
    F, p, dV = _qp(solver, u, theta)
    psi = solver.problem.material.energy

    def S(Fq, pc):
        F3 = solver.law.full_F(Fq, pc)
        return jnp.linalg.solve(F3, jax.grad(psi)(F3, pc))

    return _cell_average(_per_qp(S, F, p), dV)


def cauchy_stress(solver, u, theta):
    """Cauchy (true) stress sigma = P F^T / J per cell, ``(n_cells, 3, 3)`` (for the small-strain
    law, the symmetric stress of linear elasticity)."""
    F, p, dV = _qp(solver, u, theta)
    psi = solver.problem.material.energy

    small = not solver.problem.material.finite

    def sig(Fq, pc):
        F3 = solver.law.full_F(Fq, pc)
        P = jax.grad(psi)(F3, pc)
        if small:  # small strain: the stress is the (symmetric) derivative itself, no push-forward
            return 0.5 * (P + P.T)
        return P @ F3.T / det(F3)

    return _cell_average(_per_qp(sig, F, p), dV)


def von_mises_stress(solver, u, theta):
    """Von Mises equivalent of the Cauchy stress per cell, ``(n_cells,)``."""
    s = cauchy_stress(solver, u, theta)
    dev = s - jnp.trace(s, axis1=1, axis2=2)[:, None, None] * jnp.eye(3) / 3.0
    return jnp.sqrt(1.5 * jnp.sum(dev * dev, axis=(1, 2)))


def strain_energy(solver, u, theta):
    """Total stored energy (stress x volume; x thickness in 2D)."""
    p, X, t = solver._split(theta)
    return solver.assembler.energy(jnp.asarray(u).reshape(X.shape), X, p, t, solver.arrays["cells"])
