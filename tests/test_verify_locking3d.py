"""Nearly incompressible solids: which 3D elements lock, verified on a 3D Cook's membrane.

The panel of test_verify_cook.py ((0,0), (48,44), (48,60), (0,44) mm) extruded 4 mm in z as one
layer of bricks (``hex8``) or of six Kuhn tetrahedra per brick (``tet4``, ``tet10``), n x n in the
plane; left face clamped, u_z = 0 at every node (plane strain, so the 2D results are the
reference), a dead shear load of 100 N per mm of thickness on the right face, the MFront/OGS law
psi = K/2 (J - 1)^2 + G/2 (J^(-2/3) I1 - 3) with OGS's shear modulus G = 240.565 / (2 * 1.499) MPa
for every nu (only the bulk modulus changes). Observed: u_y of the top corner (48, 60, 0).

Reference: jaxfem's 2D tri6 plane-strain solution at n = 32 (test_verify_cook.py's setup; at
nu = 0.499 it is 6.9186 mm, 0.4 % from OGS's F-bar Q1 6.891 mm at n = 30, and tri6 is verified to
converge there): 7.4199 mm at nu = 0.45, 7.0140 at 0.49, 6.9186 at 0.499 (n = 16: 7.4024, 6.9898,
6.8916; recomputed by the slow test below).

Measured (load ~36 on 2 cores, 2026-11-25), error against that reference:

| element | n | dofs | nu = 0.45 | nu = 0.49 | nu = 0.499 |
| --- | --- | --- | --- | --- | --- |
| tet10 | 4 | 729 | | | 5.6636 (-18.1 %) |
| tet10 | 8 | 2601 | 7.2685 (-2.0 %) | 6.7496 (-3.8 %) | 6.5059 (-6.0 %) |
| tet10 | 12 | 5625 | | | 6.7052 (-3.1 %) |
| tet10 | 16 | 9801 | | | 6.7858 (-1.9 %) |
| hex8 | 8 | 486 | 6.2096 (-16.3 %) | 4.3858 (-37.5 %) | 2.6363 (-61.9 %) |
| hex8 | 16 | 1734 | 6.9812 (-5.9 %) | 5.7477 (-18.1 %) | |
| tet4 | 8 | 486 | 4.5282 (-39.0 %) | 3.0450 (-56.6 %) | 2.2979 (-66.8 %) |
| tet4 | 16 | 1734 | 6.0522 (-18.4 %) | 4.2803 (-39.0 %) | |

tet10 converges at about O(h^2) at nu = 0.499 (errors 18, 6.0, 3.1, 1.9 % at n = 4, 8, 12, 16) and
its error at a fixed mesh grows only mildly with nu: locking-free, the choice for soft nearly
incompressible foams. hex8 (full integration) and tet4 lock: their error grows several-fold as
nu -> 1/2 on the same mesh. jaxfem therefore refuses nu >= 0.45 with tet4 and hex8 in 3D
(:class:`jaxfem.ProblemError` naming tet10) and nu outside (-1, 0.5) for every element; the study
below bypasses the check by writing ``theta["nu"]`` directly.
"""

import functools

import numpy as np
import pytest

import jaxfem as jf
from tests._verify_util import MFRONT_NEO_HOOKE, node_at

E_OGS, NU_OGS = 240.565, 0.499
G = E_OGS / (2 * (1 + NU_OGS))
REFERENCE = {0.45: 7.4199, 0.49: 7.0140, 0.499: 6.9186}  # mm, 2D tri6 n = 32 (see the docstring)


def cook3d(n, element, thickness=4.0):
    """The panel extruded by ``thickness`` (mm), one layer of ``element`` cells, n x n in plane."""
    base = jf.box(0.0, 0.0, 0.0, 1.0, 1.0, thickness, n, n, 1, "hex8" if element == "hex8" else "tet4")
    xi, eta, z = base.nodes.T
    X = np.stack([48.0 * xi, (1.0 - xi) * 44.0 * eta + xi * (44.0 + 16.0 * eta), z], -1)
    mesh = jf.Mesh(X, base.cells, base.element)
    return jf.to_quadratic(mesh) if element == "tet10" else mesh


@functools.lru_cache(maxsize=None)
def cook3d_solver(n, element):
    mesh = cook3d(n, element)
    fixed = np.concatenate([jf.dofs(mesh, mesh.side("left")), jf.dofs(mesh, np.arange(mesh.n_nodes), [2])])
    problem = jf.Problem(mesh, MFRONT_NEO_HOOKE, "solid", fixed=fixed, traction_facets=mesh.side_facets("right"))
    return problem, jf.Solver(problem, options=jf.NewtonOptions(initial_step=0.25))


def cook3d_uy(n, element, nu):
    """u_y (mm) of the top corner; ``nu`` is written into the parameters directly (no refusal), so
    that the locking of linear elements can be measured."""
    problem, solver = cook3d_solver(n, element)
    theta = problem.params(E=2 * G * (1 + nu), nu=0.3, traction=np.array([0.0, 100.0 / 16.0, 0.0]))
    theta["nu"] = np.full(problem.mesh.n_cells, nu)
    return float(solver.solve(theta).u[node_at(problem.mesh, (48.0, 60.0, 0.0)), 1])


def error(n, element, nu):
    return cook3d_uy(n, element, nu) / REFERENCE[nu] - 1


@pytest.mark.slow  # 3D tet10 solves, ~30 s on 2 cores
def test_tet10_nearly_incompressible_converges_without_locking():
    e4, e8 = error(4, "tet10", 0.499), error(8, "tet10", 0.499)
    assert abs(e8) < 0.5 * abs(e4) and abs(e8) < 0.07, (e4, e8)


def test_linear_3d_elements_refused_when_nearly_incompressible():
    problem, _ = cook3d_solver(2, "hex8")
    problem.params(E=1.0, nu=0.44)
    with pytest.raises(jf.ProblemError, match="lock.*tet10"):
        problem.params(E=1.0, nu=0.45)
    tet4 = jf.Problem(jf.box(0, 0, 0, 1, 1, 1, 1, 1, 1, "tet4"), fixed=np.arange(24))
    with pytest.raises(jf.ProblemError, match="tet4 elements"):
        tet4.params(nu=np.r_[np.full(5, 0.3), 0.49])
    tet10 = jf.Problem(jf.box(0, 0, 0, 1, 1, 1, 1, 1, 1, "tet10"), fixed=np.arange(24))
    tet10.params(nu=0.499)
    for p in (tet10, tet4):
        with pytest.raises(jf.ProblemError, match=r"\(-1, 0.5\)"):
            p.params(nu=0.5)
    with pytest.raises(jf.ProblemError, match=r"\(-1, 0.5\)"):
        jf.Problem(jf.rectangle(0, 0, 1, 1, 1, 1, "tri6"), fixed=np.arange(6)).params(nu=0.6)


@pytest.mark.slow
def test_locking_study():
    # the reference itself: 2D tri6 at n = 32 (test_verify_cook's setup)
    from tests.test_verify_cook import ogs_uy
    for nu, ref in REFERENCE.items():
        assert ogs_uy(32, "tri6", nu) == pytest.approx(ref, abs=1e-3)
    tet10 = [abs(error(n, "tet10", 0.499)) for n in (4, 8, 12, 16)]
    assert np.all(np.diff(tet10) < 0) and tet10[-1] < 0.025, tet10
    for element in ("hex8", "tet4"):
        err = [error(8, element, nu) for nu in (0.45, 0.49, 0.499)]
        assert err[0] > err[1] > err[2] and err[2] < -0.5, (element, err)  # too stiff, worse as nu -> 1/2
    assert abs(error(8, "tet10", 0.45)) < 0.03 and abs(error(8, "tet10", 0.49)) < 0.05
