"""Homogeneous uniaxial stretch of a neo-Hookean bar against the closed form.

A bar free to contract laterally (only rigid motion is stopped: the left end slides on rollers,
one or two extra components pin it) is stretched by 10, 30 and 50 % through a prescribed end
displacement. For psi = mu/2 (I1 - 3) - mu ln J + lam/2 (ln J)^2 the state is homogeneous,
F = diag(s, l, l), with the lateral stretch l from the zero lateral traction condition

    P22 = mu (l - 1/l) + lam ln(s l^2) / l = 0        (solved with scipy's brentq)

and the nominal axial stress P11 = mu (s - 1/s) + lam ln(s l^2) / s. Plane stress and 3D give the
same l (the thickness stretch of plane stress is the second lateral stretch). Checked: the axial
reaction force (P11 x cross-section area, the thickness included in plane stress), the lateral
contraction of the nodes and, in plane stress, the out-of-plane stretch F33.
"""

import jax
import numpy as np
import pytest

import jaxfem as jf
from tests._verify_util import lame, uniaxial_neo_hookean

E, NU = 3.0, 0.35
MU, LAM = lame(E, NU)
L, H, THICKNESS = 4.0, 1.0, 0.7
STRETCHES = (1.1, 1.3, 1.5)


def bar(dim):
    """The bar mesh, its problem (x on the left end and the pins fixed; x of the right end
    prescribed) and the right-end nodes."""
    if dim == 2:
        mesh = jf.rectangle(0.0, 0.0, L, H, 4, 2, "quad4")
    else:
        mesh = jf.box(0.0, 0.0, 0.0, L, H, H, 4, 1, 1, "tet4")
    left, right = mesh.side("left"), mesh.side("right")
    origin = int(np.argmin(np.linalg.norm(mesh.nodes, axis=1)))
    fixed = [jf.dofs(mesh, left, 0), jf.dofs(mesh, right, 0), jf.dofs(mesh, origin, range(1, dim))]
    if dim == 3:  # rotation about the bar's axis
        fixed.append(jf.dofs(mesh, int(np.argmin(np.linalg.norm(mesh.nodes - [0, H, 0], axis=1))), 2))
    kinematics = "plane-stress" if dim == 2 else "solid"
    return mesh, jf.Problem(mesh, "neo-hookean", kinematics, fixed=np.concatenate(fixed)), right


def uniaxial_errors(dim):
    """Relative errors of the axial force and the lateral stretches at each stretch, and the
    closed-form values, as a dict of arrays."""
    mesh, problem, right = bar(dim)
    solver = jf.Solver(problem)
    area = H * THICKNESS if dim == 2 else H * H
    F_cells = jax.jit(lambda u, th: jf.deformation_gradient(solver, u, th))
    axial_force = jax.jit(lambda u, th: solver.reactions(u, th, right))
    out = {"force": [], "lateral": [], "thickness": [], "l": [], "P11": []}
    for s in STRETCHES:
        theta = problem.params(E=E, nu=NU, thickness=THICKNESS,
                               u_D=problem.prescribe(lambda X: (s - 1) * X * np.eye(dim)[0]))
        u = np.asarray(solver.solve(theta).u)
        l, P11 = uniaxial_neo_hookean(s, MU, LAM)
        force = np.asarray(axial_force(u, theta))
        out["force"].append(np.abs(force - [P11 * area, *[0] * (dim - 1)]).max() / (P11 * area))
        # every lateral coordinate scales by l (the pinned node is at the origin)
        lateral = mesh.nodes[:, 1:] * (l - 1)
        out["lateral"].append(np.abs(u[:, 1:] - lateral).max() / (1 - l))
        F33 = np.asarray(F_cells(u, theta))[:, 2, 2]
        out["thickness"].append(np.abs(F33 - l).max() / (1 - l))
        out["l"].append(l)
        out["P11"].append(P11)
    return {k: np.array(v) for k, v in out.items()}


def test_closed_form_is_linear_elasticity_at_small_stretch():
    l, P11 = uniaxial_neo_hookean(1 + 1e-7, MU, LAM)
    assert P11 / 1e-7 == pytest.approx(E, rel=1e-5)
    assert (1 - l) / 1e-7 == pytest.approx(NU, rel=1e-5)


@pytest.mark.parametrize("dim", [2, 3], ids=["plane-stress", "3d"])
def test_uniaxial_stretch_matches_closed_form(dim):
    r = uniaxial_errors(dim)
    assert np.all(r["force"] < 1e-8), r["force"]
    assert np.all(r["lateral"] < 1e-8), r["lateral"]
    assert np.all(r["thickness"] < 1e-8), r["thickness"]
    # the bar really contracted (by 14 % at 50 % stretch for nu = 0.35)
    assert r["l"][-1] < 0.87
