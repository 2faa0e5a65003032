"""Patch tests: every element reproduces a homogeneous deformation exactly on a distorted mesh.

Displacement patch test (Dirichlet): u = (F - I) X + b is prescribed on the whole boundary of a
patch whose interior nodes were moved at random. A conforming, complete element with an adequate
quadrature rule reproduces it at every interior node to round-off, the internal forces of the
exact field vanish at every interior dof, and the stress is uniform and equal to the law's closed
form. Checked for tri3, tri6 (with curved, moved mid-edge nodes), quad4, tet4, tet10 and hex8,
for the linear-elastic and the neo-Hookean law, in plane strain, plane stress and 3D, at the
finite deformation F = [[1.2, 0.1], [0.05, 0.9]] (and a 3D analogue).

Traction patch test (Neumann): the same homogeneous state is produced by the tractions P N of
its first Piola stress on every side plus just enough prescribed dofs to stop rigid motion; this
exercises the facet loads of every facet type (line2, line3, tri3, tri6, quad4) and the
"traction x thickness" convention of 2D loads, through the full Newton solve.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxfem as jf
from tests._verify_util import (F_PATCH_2D, F_PATCH_3D, full_F, lame, le_stress, nh_cauchy, nh_first_piola,
                                patch_mesh, traction_patch)

E, NU = 10.0, 0.3
MU, LAM = lame(E, NU)
LAWS = ("linear-elastic", "neo-hookean")
# Every (element, kinematics, law) combination; each Solver compiles for ~2.5 s of CPU, so the
# default suite runs a subset that still has every element, every law and every 2D
# (kinematics, law) pair, and the full matrix is marked slow.
DEFAULT = {("tri3", "plane-strain", "linear-elastic"), ("tri6", "plane-stress", "neo-hookean"),
           ("quad4", "plane-strain", "neo-hookean"), ("quad4", "plane-stress", "linear-elastic"),
           ("tet4", "solid", "neo-hookean"), ("tet10", "solid", "linear-elastic"), ("hex8", "solid", "neo-hookean")}
CASES = [pytest.param(*c, marks=() if c in DEFAULT else pytest.mark.slow)
         for c in [(el, kin, law) for el in ("tri3", "tri6", "quad4") for kin in ("plane-strain", "plane-stress")
                   for law in LAWS] + [(el, "solid", law) for el in ("tet4", "tet10", "hex8") for law in LAWS]]


def homogeneous(mesh):
    """The deformation gradient (in-plane or 3D) and the exact displacement field ``(n, dim)``."""
    F = F_PATCH_2D if mesh.dim == 2 else F_PATCH_3D
    b = np.array([0.01, -0.02, 0.03])[: mesh.dim]
    return F, mesh.nodes @ (F - np.eye(mesh.dim)).T + b


def closed_form_piola(F, kinematics, law):
    F3 = full_F(F, kinematics, law, MU, LAM)
    return F3, (le_stress if law == "linear-elastic" else nh_first_piola)(F3, MU, LAM)


def displacement_patch(element, kinematics, law):
    """Solve the displacement patch test; relative errors of the interior displacements, of the
    interior internal forces of the exact field, of F, P and (neo-Hookean) the Cauchy stress."""
    mesh = patch_mesh(element)
    F, exact = homogeneous(mesh)
    problem = jf.Problem(mesh, law, kinematics, fixed=jf.dofs(mesh, mesh.boundary_nodes()))
    solver = jf.Solver(problem)
    theta = problem.params(E=E, nu=NU, u_D=problem.prescribe(exact))
    u = np.asarray(solver.solve(theta).u)
    interior = np.setdiff1d(np.arange(mesh.n_nodes), mesh.boundary_nodes())
    assert len(interior) >= 8
    R, F_fem, P_fem, s_fem = (np.asarray(a) for a in jax.jit(lambda u, th: (
        solver.residual(jnp.asarray(exact).ravel(), th), jf.deformation_gradient(solver, u, th),
        jf.first_piola_stress(solver, u, th), jf.cauchy_stress(solver, u, th)))(u, theta))
    free = problem.free_mask
    F3, P = closed_form_piola(F, kinematics, law)
    scale = np.abs(P).max()
    return {
        "u": np.abs(u[interior] - exact[interior]).max() / np.abs(exact).max(),
        "residual": np.abs(R[free]).max() / np.abs(R[~free]).max(),
        "F": np.abs(F_fem - F3).max(),
        "P": np.abs(P_fem - P).max() / scale,
        "cauchy": np.abs(s_fem - nh_cauchy(F3, MU, LAM)).max() / scale if law == "neo-hookean" else 0.0,
    }


@pytest.mark.parametrize("element, kinematics, law", CASES)
def test_displacement_patch(element, kinematics, law):
    err = displacement_patch(element, kinematics, law)
    # the interior nodes follow the homogeneous field and the exact field's internal forces
    # cancel at every interior dof ...
    assert err["u"] < 1e-10 and err["residual"] < 1e-12, err
    # ... and the stress is uniform and equal to the closed form
    assert err["F"] < 1e-10 and err["P"] < 1e-9 and err["cauchy"] < 1e-9, err


@pytest.mark.parametrize("element, kinematics, thickness", [
    pytest.param("quad4", "plane-strain", 1.0, marks=pytest.mark.slow),  # line2 facets (also in Cook)
    ("tri6", "plane-stress", 0.5),    # line3 facets (curved cells), load = traction x thickness
    pytest.param("tet4", "solid", 1.0, marks=pytest.mark.slow),          # tri3 facets
    ("tet10", "solid", 1.0),          # tri6 facets
    ("hex8", "solid", 1.0),           # quad4 facets
])
def test_traction_patch(element, kinematics, thickness):
    err, reaction = traction_patch_errors(element, kinematics, thickness)
    assert err < 1e-9, f"traction-driven patch misses the homogeneous field by {err:.2e}"
    assert reaction < 1e-9  # the constraints only stop rigid motion: no reactions


def traction_patch_errors(element, kinematics, thickness):
    """Relative error of the displacements and largest reaction / |P| of the traction patch test."""
    mesh = patch_mesh(element, seed=1)
    F, exact = homogeneous(mesh)
    F3, P = closed_form_piola(F, kinematics, "neo-hookean")
    facets, loads = traction_patch(mesh, P, thickness)
    # rigid motion only: one node fully, and one (2D) or three (3D) more components
    lo, hi = mesh.bounds()
    corner = lambda p: int(np.argmin(np.linalg.norm(mesh.nodes - p, axis=1)))  # noqa: E731
    o, x = corner(lo), corner([hi[0], *lo[1:]])
    fixed = [jf.dofs(mesh, o), jf.dofs(mesh, x, 1)]
    if mesh.dim == 3:
        fixed += [jf.dofs(mesh, x, 2), jf.dofs(mesh, corner([lo[0], hi[1], lo[2]]), 2)]
    problem = jf.Problem(mesh, "neo-hookean", kinematics, fixed=np.concatenate(fixed), traction_facets=facets)
    solver = jf.Solver(problem)
    theta = problem.params(E=E, nu=NU, thickness=thickness, u_D=problem.prescribe(exact), traction=loads)
    u = np.asarray(solver.solve(theta).u)
    reaction = np.abs(np.asarray(jax.jit(solver.reactions)(u, theta))).max() / np.abs(P).max()
    return np.abs(u - exact).max() / np.abs(exact).max(), reaction
