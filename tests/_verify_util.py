"""Shared helpers of the verification tests (``tests/test_verify_*.py``).

Everything here is independent of jaxfem's own formulas: meshes are built with jaxfem's generators
(the object under test) but the closed-form stresses, the lateral stretches of a uniaxial bar and
the probes are written out by hand from the strain-energy densities, in numpy and scipy.

Units are whatever the caller uses consistently (the Cook tests use mm, N/mm^2 and N).
"""

from __future__ import annotations

import functools

import jax.numpy as jnp
import numpy as np
from scipy.optimize import brentq

import jaxfem as jf
from jaxfem._small import det

#: A homogeneous finite deformation for the patch tests (the issue's example) and a 3D one.
F_PATCH_2D = np.array([[1.2, 0.1], [0.05, 0.9]])
F_PATCH_3D = np.array([[1.2, 0.1, -0.05], [0.05, 0.9, 0.08], [-0.04, 0.06, 1.1]])


# ====================================================================== meshes
def distort(mesh: jf.Mesh, amplitude: float, seed: int, movable: np.ndarray | None = None) -> jf.Mesh:
    """``mesh`` with its interior nodes (or the nodes ``movable``) moved by independent uniform
    random offsets in ``[-amplitude, amplitude]`` per coordinate; checked for inverted cells."""
    rng = np.random.default_rng(seed)
    if movable is None:
        movable = np.setdiff1d(np.arange(mesh.n_nodes), mesh.boundary_nodes())
    X = mesh.nodes.copy()
    X[movable] += rng.uniform(-amplitude, amplitude, (len(movable), mesh.dim))
    return mesh.with_nodes(X)


def patch_mesh(element: str, seed: int = 0) -> jf.Mesh:
    """A distorted patch of ``element`` cells: the rectangle [0, 2] x [0, 1] (5 x 3 squares) or the
    unit cube (3 x 3 x 3 bricks), interior vertices moved by up to a quarter (2D) or a fifth (3D)
    of the spacing. Quadratic cells get straight edges through the moved vertices; ``tri6`` then
    has its interior mid-edge nodes moved as well (curved cells, still isoparametric)."""
    if element in ("tri3", "tri6", "quad4"):
        base = jf.rectangle(0.0, 0.0, 2.0, 1.0, 5, 3, "quad4" if element == "quad4" else "tri3")
        mesh = distort(base, 0.25 * 0.33, seed)
        if element == "tri6":
            mesh = jf.to_quadratic(mesh)
            mids = np.setdiff1d(np.arange(base.n_nodes, mesh.n_nodes), mesh.boundary_nodes())
            mesh = distort(mesh, 0.025, seed + 1, mids)
        return mesh
    base = jf.box(0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 3, 3, 3, "hex8" if element == "hex8" else "tet4")
    mesh = distort(base, 0.2 / 3, seed)
    return jf.to_quadratic(mesh) if element == "tet10" else mesh


def cook_mesh(n: int, element: str) -> jf.Mesh:
    """Cook's membrane, corners (0,0), (48,44), (48,60), (0,44) (mm): a structured ``n x n`` mesh of
    the unit square mapped bilinearly onto the trapezoid (as the deal.II gallery's
    ``grid_y_transform``); ``tri6`` gets its mid-edge nodes after the mapping."""
    base = jf.rectangle(0.0, 0.0, 1.0, 1.0, n, n, "quad4" if element == "quad4" else "tri3")
    xi, eta = base.nodes[:, 0], base.nodes[:, 1]
    X = np.stack([48.0 * xi, (1.0 - xi) * 44.0 * eta + xi * (44.0 + 16.0 * eta)], -1)
    mesh = jf.Mesh(X, base.cells, base.element)
    return jf.to_quadratic(mesh) if element == "tri6" else mesh


def node_at(mesh: jf.Mesh, point, tol: float = 1e-9) -> int:
    """Index of the node at ``point`` (an error if there is none)."""
    d = np.linalg.norm(mesh.nodes - np.asarray(point, float), axis=1)
    k = int(np.argmin(d))
    assert d[k] <= tol, f"no node at {point}: nearest is {mesh.nodes[k]}"
    return k


# ====================================================================== closed forms (numpy)
def lame(E, nu):
    """``(mu, lam)`` from Young's modulus and Poisson's ratio."""
    return E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))


def nh_first_piola(F, mu, lam):
    """First Piola stress of psi = mu/2 (I1 - 3) - mu ln J + lam/2 (ln J)^2 (3x3 F):
    P = mu (F - F^-T) + lam ln J F^-T."""
    Fit = np.linalg.inv(F).T
    return mu * (F - Fit) + lam * np.log(np.linalg.det(F)) * Fit


def nh_cauchy(F, mu, lam):
    """Cauchy stress of the same law: sigma = (mu (b - I) + lam ln J I) / J."""
    J = np.linalg.det(F)
    return (mu * (F @ F.T - np.eye(3)) + lam * np.log(J) * np.eye(3)) / J


def le_stress(F, mu, lam):
    """Small-strain stress lam tr(eps) I + 2 mu eps with eps = sym(F) - I (3x3 F); it is also the
    first Piola stress dpsi/dF of jaxfem's linear-elastic energy."""
    eps = 0.5 * (F + F.T) - np.eye(3)
    return lam * np.trace(eps) * np.eye(3) + 2 * mu * eps


def embed(F2, f33):
    F = np.zeros((3, 3))
    F[:2, :2], F[2, 2] = F2, f33
    return F


def full_F(F, kinematics, law, mu, lam):
    """The 3x3 deformation gradient of an in-plane ``F`` under ``kinematics``; for plane stress the
    out-of-plane stretch solves P33 = 0 (brentq on the closed form, not jaxfem's Newton)."""
    if kinematics == "solid":
        return np.asarray(F, float)
    if kinematics == "plane-strain":
        return embed(F, 1.0)
    if law == "linear-elastic":
        e11, e22 = F[0, 0] - 1, F[1, 1] - 1
        return embed(F, 1 - lam * (e11 + e22) / (lam + 2 * mu))
    J2 = np.linalg.det(F)
    return embed(F, brentq(lambda l: mu * (l - 1 / l) + lam * np.log(J2 * l) / l, 1e-3, 10.0, xtol=1e-15))


def uniaxial_neo_hookean(stretch, mu, lam):
    """Homogeneous uniaxial stress of the neo-Hookean law: the lateral stretch l (both lateral
    directions free, so equal) from P22 = mu (l - 1/l) + lam ln(stretch l^2) / l = 0, and the
    nominal axial stress P11 = mu (stretch - 1/stretch) + lam ln(stretch l^2) / stretch."""
    l = brentq(lambda l: mu * (l * l - 1) + lam * np.log(stretch * l * l), 1e-6, 1.0, xtol=1e-15, rtol=1e-15)
    return l, mu * (stretch - 1 / stretch) + lam * np.log(stretch * l * l) / stretch


# ====================================================================== other laws as jaxfem Materials
def _gallery_energy(F, p):
    # deal.II code gallery "Quasi-static finite-strain compressible elasticity" (cook_membrane.cc):
    # psi = kappa/4 (J^2 - 1 - 2 ln J) + mu/2 (J^(-2/3) I1 - 3), kappa = lambda + 2/3 mu.
    mu, lam = jf.lame(p["E"], p["nu"])
    J = det(F)
    return 0.25 * (lam + 2 * mu / 3) * (J**2 - 1 - 2 * jnp.log(J)) + 0.5 * mu * (J ** (-2 / 3) * jnp.sum(F * F) - 3)


def _mfront_energy(F, p):
    # MFront/OpenGeoSys "NeoHooke" (de Souza Neto et al. 1996): psi = K/2 (J - 1)^2 + G/2 (J^(-2/3) I1 - 3).
    mu, lam = jf.lame(p["E"], p["nu"])
    J = det(F)
    return 0.5 * (lam + 2 * mu / 3) * (J - 1) ** 2 + 0.5 * mu * (J ** (-2 / 3) * jnp.sum(F * F) - 3)


GALLERY_NEO_HOOKE = jf.Material("dealii-gallery-neo-hooke", _gallery_energy)
MFRONT_NEO_HOOKE = jf.Material("mfront-neo-hooke", _mfront_energy)


# ====================================================================== jaxfem probes
def traction_patch(mesh: jf.Mesh, P, thickness: float = 1.0):
    """Boundary facets of a box-shaped mesh and the dead load ``P N`` on each (times the thickness
    in 2D), ``(facets, loads)``: the tractions of the homogeneous first Piola stress ``P``."""
    names = ["left", "right", "bottom", "top", "back", "front"][: 2 * mesh.dim]
    facets, loads = [], []
    for k, name in enumerate(names):
        f = mesh.side_facets(name)
        N = np.zeros(mesh.dim)
        N[k // 2] = -1.0 if k % 2 == 0 else 1.0
        facets.append(f)
        loads.append(np.tile(thickness * (P[: mesh.dim, : mesh.dim] @ N), (len(f), 1)))
    return np.concatenate(facets), np.concatenate(loads)


# ====================================================================== shared solves
@functools.lru_cache(maxsize=None)
def pulled_block(kinematics: str = "plane-strain"):
    """A neo-Hookean block [0, 2] x [0, 1] (x [0, 1] in 3D; E = 10, nu = 0.3) on a distorted mesh
    (P1 in 2D, hex8 in 3D), clamped on the left and pulled on the right by the dead traction that
    stretches a free bar by 20 % (P11 of :func:`uniaxial_neo_hookean`): a non-homogeneous finite
    stretch of about 18-20 %. Returns ``(mesh, problem, solver, theta, solution)``; cached, so the
    test files share one compilation."""
    if kinematics == "solid":
        mesh = distort(jf.box(0.0, 0.0, 0.0, 2.0, 1.0, 1.0, 6, 3, 3, "hex8"), 0.05, seed=3)
    else:
        mesh = distort(jf.rectangle(0.0, 0.0, 2.0, 1.0, 10, 5, "tri3"), 0.05, seed=3)
    problem = jf.Problem(mesh, "neo-hookean", kinematics, fixed=jf.dofs(mesh, mesh.side("left")),
                         traction_facets=mesh.side_facets("right"))
    solver = jf.Solver(problem)
    load = np.zeros(mesh.dim)
    load[0] = uniaxial_neo_hookean(1.2, *lame(10.0, 0.3))[1]
    theta = problem.params(E=10.0, nu=0.3, traction=load)
    return mesh, problem, solver, theta, solver.solve(theta)
