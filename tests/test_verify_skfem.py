"""Agreement with an independent implementation: scikit-fem on the same meshes.

scikit-fem (a test-only dependency) assembles with its own elements, quadrature, mappings and
boundary handling; nothing is shared with jaxfem but the node coordinates and cells. Agreement to
round-off on the same discretisation checks jaxfem's assembly, loads, constraints and material
derivatives as a whole.

- Linear elasticity, plane strain (``skfem.models.elasticity``): Cook's panel, clamped left edge,
  shear load on the right edge; tri6 (P2) and quad4 (Q1, 2 x 2 Gauss points on both sides).
  Same discrete solution to 1e-8 relative.
- Neo-Hookean, plane strain, with a Newton loop written here on scikit-fem's BilinearForm and
  LinearForm (residual from P = mu (F - F^-T) + lam ln J F^-T and its hand-derived linearisation):
  a block clamped on one end and pulled by a dead load to about 20 % stretch, and Cook's panel
  under its finite-strain shear load (bundle law), on P1 meshes. Same solution to 1e-6 (in fact
  ~1e-12).
"""

import numpy as np
import pytest
import skfem
from skfem.helpers import ddot, det, grad, identity, inv, transpose
from skfem.models.elasticity import lame_parameters, linear_elasticity

import jaxfem as jf
from tests._verify_util import cook_mesh, lame, pulled_block


# ====================================================================== scikit-fem side
def sk_basis(mesh: jf.Mesh, intorder=None):
    """scikit-fem vector basis on jaxfem's mesh and the map (jaxfem node, component) -> skfem dof."""
    if mesh.element == "quad4":
        m, el = skfem.MeshQuad(mesh.nodes.T, mesh.cells.T), skfem.ElementQuad1()
    else:
        n_vertices = mesh.cells[:, :3].max() + 1  # jaxfem numbers the mid-edge nodes last
        m = skfem.MeshTri(mesh.nodes[:n_vertices].T, mesh.cells[:, :3].T)
        el = skfem.ElementTriP2() if mesh.element == "tri6" else skfem.ElementTriP1()
    basis = skfem.Basis(m, skfem.ElementVector(el), intorder=intorder)
    dof = np.zeros((mesh.n_nodes, 2), np.int64)
    dof[: m.p.shape[1]] = basis.nodal_dofs.T
    if mesh.element == "tri6":  # mid-edge nodes <-> scikit-fem's facet dofs
        edges = np.sort(mesh.cells[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
        mids = mesh.cells[:, 3:6].ravel()
        facet_of = {tuple(v): k for k, v in enumerate(np.sort(m.facets.T, axis=1))}
        for (a, b), node in zip(edges, mids):
            dof[node] = basis.facet_dofs[:, facet_of[(a, b)]]
    assert np.allclose(basis.doflocs[:, dof[:, 0]].T, mesh.nodes)
    return basis, dof


def sk_line_load(basis, where, load):
    """Consistent nodal forces of a constant load per unit length on the facets ``where(x)``."""
    fb = skfem.FacetBasis(basis.mesh, basis.elem, facets=basis.mesh.facets_satisfying(where))
    return skfem.LinearForm(lambda v, w: load[0] * v[0] + load[1] * v[1]).assemble(fb)


def nh_forms(mu, lam):
    def mm(A, B):
        return np.einsum("ij...,jk...->ik...", A, B)

    def kinematics(w):
        F = identity(grad(w["u"])) + grad(w["u"])
        return F, transpose(inv(F)), np.log(det(F))

    @skfem.LinearForm
    def residual(v, w):
        F, Fit, lnJ = kinematics(w)
        return ddot(mu * (F - Fit) + lam * lnJ * Fit, grad(v))

    @skfem.BilinearForm
    def tangent(du, v, w):
        F, Fit, lnJ = kinematics(w)
        dF = grad(du)
        dP = mu * dF + (mu - lam * lnJ) * mm(mm(Fit, transpose(dF)), Fit) + lam * ddot(Fit, dF) * Fit
        return ddot(dP, grad(v))

    return residual, tangent


def sk_neo_hookean(basis, mu, lam, fixed, u_fixed, f_ext, steps):
    """Newton with load steps on scikit-fem forms: returns the equilibrium dof vector."""
    residual, tangent = nh_forms(mu, lam)
    u = np.zeros(basis.N)
    for s in np.linspace(0, 1, steps + 1)[1:]:
        u[fixed] = s * u_fixed
        for _ in range(30):
            w = basis.interpolate(u)
            R = residual.assemble(basis, u=w) - s * f_ext
            du = skfem.solve(*skfem.condense(tangent.assemble(basis, u=w), -R, D=fixed))
            u += du
            if np.linalg.norm(du) < 1e-13 * np.linalg.norm(u):
                break
        else:
            raise AssertionError("scikit-fem Newton did not converge")
    return u


# ====================================================================== comparisons
def linear_cook_difference(element):
    """max |u_jaxfem - u_skfem| / max |u| for linear plane-strain elasticity on Cook's panel."""
    E, nu = 1.0, 1 / 3
    mesh = cook_mesh(4 if element == "tri6" else 8, element)
    basis, dof = sk_basis(mesh, intorder=3 if element == "quad4" else None)
    lam, mu = lame_parameters(E, nu)
    K = linear_elasticity(lam, mu).assemble(basis)
    f = sk_line_load(basis, lambda x: np.isclose(x[0], 48.0), [0.0, 1 / 16])
    u_sk = skfem.solve(*skfem.condense(K, f, D=basis.get_dofs(lambda x: np.isclose(x[0], 0.0))))[dof]

    problem = jf.Problem(mesh, "linear-elastic", "plane-strain", fixed=jf.dofs(mesh, mesh.side("left")),
                         traction_facets=mesh.side_facets("right"))
    u = np.asarray(jf.Solver(problem).solve(problem.params(E=E, nu=nu, traction=[0.0, 1 / 16])).u)
    return np.abs(u - u_sk).max() / np.abs(u_sk).max()


@pytest.mark.parametrize("element", ["tri6", pytest.param("quad4", marks=pytest.mark.slow)])
def test_linear_elasticity_matches_scikit_fem(element):
    assert linear_cook_difference(element) < 1e-8


def pulled_block_difference():
    """Block [0, 2] x [0, 1] (distorted P1 mesh) clamped on the left and pulled on the right by a
    dead load that stretches it by about 18 %, plane-strain neo-Hookean (``pulled_block``):
    relative difference of the fields, and jaxfem's solution."""
    mesh, problem, solver, theta, sol = pulled_block("plane-strain")
    mu, lam = lame(float(theta["E"][0]), float(theta["nu"][0]))
    basis, dof = sk_basis(mesh)
    load = np.asarray(theta["traction"][0])
    f = sk_line_load(basis, lambda x: np.isclose(x[0], 2.0), load)
    fixed = dof.ravel()[problem.fixed]
    u_sk = sk_neo_hookean(basis, mu, lam, fixed, np.zeros(len(fixed)), f, 4)[dof]
    return np.abs(np.asarray(sol.u) - u_sk).max() / np.abs(u_sk).max(), sol


def test_neo_hookean_stretch_matches_scikit_fem():
    diff, sol = pulled_block_difference()
    assert diff < 1e-6
    u = np.asarray(sol.u)
    assert u[:, 0].max() > 0.3  # a finite stretch (right end moved by about 18 % of the length)
    assert np.ptp(u[:, 1]) > 0.05  # and not homogeneous: the clamped end keeps its width


def cook_bundle_difference(n=8):
    """Cook's panel with the bundle's neo-Hookean law (plane strain, mu = 0.4225, nu = 0.3, load 1),
    P1: relative field difference and jaxfem's vertical displacement at (48, 52)."""
    mu_, nu = 0.4225, 0.3
    E = 2 * mu_ * (1 + nu)
    mu, lam = lame(E, nu)
    mesh = cook_mesh(n, "tri3")
    basis, dof = sk_basis(mesh)
    left = mesh.side("left")
    f = sk_line_load(basis, lambda x: np.isclose(x[0], 48.0), [0.0, 1 / 16])
    u_sk = sk_neo_hookean(basis, mu, lam, dof[left].ravel(), np.zeros(2 * len(left)), f, 10)[dof]

    problem = jf.Problem(mesh, "neo-hookean", "plane-strain", fixed=jf.dofs(mesh, left),
                         traction_facets=mesh.side_facets("right"))
    u = np.asarray(jf.Solver(problem).solve(problem.params(E=E, nu=nu, traction=[0.0, 1 / 16])).u)
    mid = int(np.argmin(np.linalg.norm(mesh.nodes - [48.0, 52.0], axis=1)))
    return np.abs(u - u_sk).max() / np.abs(u_sk).max(), u[mid, 1]


def test_neo_hookean_cook_matches_scikit_fem():
    diff, uy = cook_bundle_difference()
    assert diff < 1e-6
    assert uy == pytest.approx(13.43, abs=0.01)  # large deformation: 28 % of the panel's width
