"""The problems of benchmarks/forward.py: a neo-Hookean sheet (tri3) and block (hex8) stretched 20 %,
and torch-fem's own neo-Hookean benchmark (a unit cube stretched to 20x), with the size sweeps."""

from __future__ import annotations

import numpy as np

import jaxfem as jf

E_SHEET, NU = 83.76, 0.3
SHEET = (100.0, 60.0)             # sheet length x height; cells are squares (nx : ny = 5 : 3)
BLOCK = (2.0, 1.0, 1.0)           # block lengths; cubic cells (nx = 2 n, ny = nz = n)
STRETCH = 0.2

SIZES_2D = {"quick": [(10, 6), (40, 24)], "default": [(40, 24), (65, 39), (130, 78), (205, 123)],
            "full": [(40, 24), (65, 39), (130, 78), (205, 123), (290, 174), (410, 246), (580, 348)]}
SIZES_3D = {"quick": [3, 6], "default": [6, 11], "full": [6, 11, 16, 20, 25]}
DOC_N = {"quick": [5], "default": [5, 9], "full": [5, 9, 13]}   # torch-fem's own benchmark sizes
DOC = {"E": 1000.0, "nu": 0.3, "U": 19.0, "n_inc": 21}          # as in torch-fem's benchmark


def sheet(nx, ny, kinematics="plane-stress"):
    L, H = SHEET
    mesh = jf.rectangle(0, 0, L, H, nx, ny)
    left, right = mesh.side("left"), mesh.side("right")
    corner = left[np.argmin(mesh.nodes[left, 1])]
    fixed = np.concatenate([jf.dofs(mesh, left, 0), jf.dofs(mesh, right, 0), jf.dofs(mesh, [corner], 1)])
    pb = jf.Problem(mesh, "neo-hookean", kinematics, fixed=fixed)
    theta = pb.params(E=E_SHEET, nu=NU, u_D=pb.prescribe(lambda X: STRETCH * X * np.array([1.0, 0.0])))
    return pb, theta, right


def block(n):
    Lx, Ly, Lz = BLOCK
    mesh = jf.box(0, 0, 0, Lx, Ly, Lz, 2 * n, n, n, "hex8")
    X = mesh.nodes
    left, right = mesh.side("left"), mesh.side("right")
    a = np.flatnonzero((X[:, 0] == 0) & (X[:, 1] == 0) & (X[:, 2] == 0))
    b = np.flatnonzero((X[:, 0] == 0) & (np.isclose(X[:, 1], Ly)) & (X[:, 2] == 0))
    fixed = np.concatenate([jf.dofs(mesh, left, 0), jf.dofs(mesh, right, 0), jf.dofs(mesh, a, 1),
                            jf.dofs(mesh, a, 2), jf.dofs(mesh, b, 2)])
    pb = jf.Problem(mesh, "neo-hookean", "solid", fixed=fixed)
    theta = pb.params(E=E_SHEET, nu=NU, u_D=pb.prescribe(lambda X: STRETCH * X * np.array([1.0, 0, 0])))
    return pb, theta, right


def torchfem_cube(N):
    """torch-fem's benchmark problem (benchmarks/hyperelasticity.py) as a jaxfem problem: unit cube of
    (N-1)^3 hexahedra, x fixed on the left face and prescribed (U) on the right, y fixed on the plane
    y = 0.5 and z on z = 0.5, E = 1000, nu = 0.3."""
    mesh = jf.box(0, 0, 0, 1, 1, 1, N - 1, N - 1, N - 1, "hex8")
    X = mesh.nodes
    left, right = np.flatnonzero(X[:, 0] == 0), np.flatnonzero(X[:, 0] == 1)
    fixed = np.concatenate([jf.dofs(mesh, left, 0), jf.dofs(mesh, right, 0),
                            jf.dofs(mesh, np.flatnonzero(X[:, 1] == 0.5), 1),
                            jf.dofs(mesh, np.flatnonzero(X[:, 2] == 0.5), 2)])
    pb = jf.Problem(mesh, "neo-hookean", "solid", fixed=fixed)
    U = np.zeros_like(X)
    U[right, 0] = DOC["U"]
    return pb, pb.params(E=DOC["E"], nu=DOC["nu"], u_D=pb.prescribe(U)), right

