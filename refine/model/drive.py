"""Derivatives of a :class:`~refine.model.MeasuredModel`'s prediction with respect to the
measured boundary displacements that drive it (the drive covariance of
:mod:`refine.diagnosis.uncertainty` needs rows of them).

Two ways to the rows ``C dP/dB`` of ``c`` cotangents ``C``: forward, the whole Jacobian by one
tangent solve per boundary value and frame (:func:`boundary_jacobian`: one back-substitution
each on the host, :meth:`jaxfem.Solver.solve_with_prescribed_tangents`); reverse, one adjoint solve per cotangent and frame
(:func:`boundary_vjp`'s pull-back, which compiles the adjoint program and the points'
pull-back for the model's bucket). :func:`boundary_vjp` takes the forward way where the boundary
values are few (at most :data:`FORWARD_BATCHES` batches of tangents over all frames: a
~300-point bundle of 4 frames, ~130 boundary values a frame), the reverse one where they are
many (3,000 points x 11 frames: ~450 boundary values a frame, most of a diagnosis's CPU seconds
forward).
"""

from __future__ import annotations

import jax
import numpy as np
from jaxfem.padding import BATCH

from refine.model.measured import frame_traction

#: the most tangent batches (of :data:`jaxfem.padding.BATCH` directions, over all frames) for
#: which :func:`boundary_vjp` takes the forward way: ~64 batches cost about a second on a
#: ~2,400-cell quadratic mesh, less than compiling the adjoint and the points' pull-back
FORWARD_BATCHES = 96


def boundary_jacobian(model, theta) -> np.ndarray:
    """Derivatives of ``model``'s prediction ``(n_frames, n_points, dim)`` with respect to the
    measured boundary displacements ``(n_frames, n_boundary * dim)``
    (:meth:`~refine.model.MeasuredModel.measured_boundary`), as ``(n_frames, n_points, dim,
    n_frames, n_boundary * dim)``: zero between different frames (each frame's equilibrium
    depends on its own drive only). On the solver's shared programs (one tangent solve per
    boundary value and frame) where the model :attr:`~refine.model.MeasuredModel.shares_programs`;
    else by forward mode through the model's own solve. Rows of it alone: :func:`boundary_vjp`."""
    B = model.measured_boundary()
    if not model.shares_programs:
        return np.asarray(jax.jit(jax.jacfwd(lambda b: model.predict(theta, boundary=b)))(B))
    n_f, m = B.shape
    start, U, dU, T = model.frame_starts(theta), [], [], model.frame_tractions(theta["X"])
    for f in range(n_f):
        D = model.drives[f].matrix  # (n_fixed, m): u_D = D @ B[f], so the directions are its columns
        loads = {"u_D": D @ B[f], **frame_traction(T, f)}
        u, du, _ = model.solver.solve_with_prescribed_tangents({**theta, **loads}, D.T, start=start)
        start = (np.asarray(u).reshape(-1), {**start[1], **loads})
        U.append(u)
        dU.append(du)
    dU = np.stack(dU, 1)  # (m, frames, n_nodes, dim)
    _, dP = model.at_points_and_derivatives(np.stack(U), dU, theta["X"], np.zeros((m,) + np.shape(theta["X"])))
    dP = np.moveaxis(dP, 0, -1)  # (frames, points, dim, m)
    out = np.zeros(dP.shape[:3] + (n_f, m))
    for f in range(n_f):
        out[f, :, :, f] = dP[f]
    return out


def boundary_vjp(model, theta, cotangents, forward_batches: int = FORWARD_BATCHES) -> np.ndarray:
    """Cotangents of the measured boundary displacements ``(c, n_frames, n_boundary * dim)``
    from ``c`` cotangents of ``model``'s prediction ``cotangents (c, n_frames, n_points, dim)``:
    the rows ``C dP/dB`` of :func:`boundary_jacobian`, for a model that
    :attr:`~refine.model.MeasuredModel.shares_programs`. Forward (that Jacobian, contracted)
    where its tangents take at most ``forward_batches`` batches over all frames, else one
    adjoint solve per cotangent and frame (see the module doc)."""
    C = np.asarray(cotangents, np.float64)
    B = model.measured_boundary()
    if B.shape[0] * -(-B.shape[1] // BATCH) <= forward_batches:
        return np.einsum("cfpd,fpdgm->cgm", C, boundary_jacobian(model, theta))
    start, out = model.frame_starts(theta), np.zeros(C.shape[:2] + (B.shape[1],))
    T = model.frame_tractions(theta["X"])
    for f in range(len(B)):
        D = model.drives[f].matrix  # (n_fixed, m): u_D = D @ B[f]
        loads = {"u_D": D @ B[f], **frame_traction(T, f)}
        u, state = model.solver.solve_for_adjoint({**theta, **loads}, start=start)
        start = (np.asarray(u).reshape(-1), {**start[1], **loads})
        gU = np.asarray(model.points_vjp(np.asarray(u)[None], theta["X"], C[:, f:f + 1]))[:, 0]  # (c, nodes, dim)
        for i, g in enumerate(gU):
            out[i, f] = D.T @ np.asarray(model.solver.adjoint(state, g)["u_D"])
    return out
