"""Forward kinematics: each bone's rigid motion from the joint angles, and the nodal displacements
that prescribe it (the bones are kinematic constraints, Dirichlet values, not stiff material).

A bone's joint turns it against its parent about axes through the joint's pivot (reference
coordinates), the first axis outermost: ``x = T_parent(R_1(a_1) R_2(a_2) (X - p) + p)``. So a
phalanx turns about its one axis, the wrist about two, and a child follows its parent.
"""

from __future__ import annotations

import numpy as np

from jaxfem.exceptions import ProblemError
from .body import Body


def rotation(axis, angle, xp=np):
    """The rotation matrix ``(3, 3)`` by ``angle`` radians about ``axis (3,)`` (right hand; Rodrigues).
    ``xp``: the array module (``numpy``, or ``jax.numpy`` for an angle that is traced)."""
    k = np.asarray(axis, float)
    k = k / np.linalg.norm(k)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + xp.sin(angle) * K + (1 - xp.cos(angle)) * (K @ K)


def bone_transforms(body: Body, angles: dict, xp=np) -> dict:
    """Each bone's rigid motion ``{name: (R (3, 3), t (3,))}``, ``x = R X + t``, for the joint
    ``angles`` ``{angle name: radians}`` (angles not given are 0). ``xp``: the array module
    (``jax.numpy``: differentiable in the angles).

    Raises:
        ProblemError: an angle name that no joint has.
    """
    unknown = set(angles) - set(body.angle_names)
    if unknown:
        raise ProblemError(f"no joint has the angle(s) {sorted(unknown)}; the hand's angles are {body.angle_names}")
    out = {}
    for bone in body.bones:
        if bone.joint is None:
            out[bone.name] = (np.eye(3), np.zeros(3))
            continue
        R = np.eye(3)
        for axis, name in zip(bone.joint.axes, bone.joint.names):
            R = R @ rotation(axis, angles.get(name, 0.0), xp)
        p = np.asarray(bone.joint.pivot, float)
        Rp, tp = out[bone.parent]
        out[bone.name] = (Rp @ R, Rp @ (p - R @ p) + tp)
    return out


def bone_displacements(hand, angles: dict, xp=np):
    """Displacements ``(n_nodes, 3)`` (mm) that move every bone's nodes rigidly for ``angles``
    (radians); zero at every other node. ``xp=jax.numpy``: a JAX array, differentiable in the angles
    (the kinematic Dirichlet data of a fit of joint angles)."""
    U = xp.zeros(hand.mesh.nodes.shape)
    for name, (R, t) in bone_transforms(hand.body, angles, xp).items():
        nodes = hand.bone_nodes[name]
        X = hand.mesh.nodes[nodes]
        move = X @ R.T + t - X
        if xp is np:
            U[nodes] = move
        else:
            U = U.at[nodes].set(move)
    return U
