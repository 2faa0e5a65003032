"""Small-strain limit: Kirsch's plate with a circular hole under remote uniaxial tension.

An infinite plate with a hole of radius R under remote tension s0 along x has the stress field of
Kirsch (1898); on the hole the hoop stress is s0 (1 - 2 cos 2 theta): 3 s0 at the top point
(0, R), where it is sigma_xx, and -s0 at (R, 0).

The plate here is the square [-10 R, 10 R]^2 meshed by ``jaxfem.plate`` (tri6, mid-edge nodes on
the hole). Instead of a finite-width correction (Howland's strip value 3.03 at d/W = 0.1 does not
fit a square plate loaded on two sides: that plate gives about 3.08), its four sides carry the
exact Kirsch tractions sigma_Kirsch . n (one constant vector per facet, at the facet's mid-point),
so the exact solution of the truncated problem is Kirsch's field itself and the concentration
factor must tend to exactly 3.

Hoop stress on the hole, from the boundary trace of the displacement: the hole is traction free,
so sigma_rr = sigma_rtheta = 0 there and, in plane stress, sigma_thetatheta = E eps_tt with
eps_tt = t . du/ds the stretch of the boundary curve (the quadratic trace of each facet,
differentiated at its nodes, averaged between the two facets at a vertex). This recovery is far
more accurate than a cell average next to the hole.

``plate`` has no local size control: the hole gets 30-degree chords (12 facets) unless the global
size h is below R pi/6, so h = 0.5 R (14.7k dofs) is the default case and h = 0.25 R (58k dofs)
the slow one.

The same plate with the neo-Hookean law at a tiny load (s0 = 1e-5 E) must give the linear field.
"""

import jax
import numpy as np
import pytest

import jaxfem as jf

R, HALF = 1.0, 10.0
E, NU = 1.0, 0.3
S0 = 1e-5 * E


def kirsch_stress(x, s0, a=R):
    """Kirsch's stress field (2x2 Cartesian components) at points ``x`` ``(n, 2)``."""
    r, t = np.hypot(x[:, 0], x[:, 1]), np.arctan2(x[:, 1], x[:, 0])
    q = (a / r) ** 2
    srr = s0 / 2 * (1 - q) + s0 / 2 * (1 - 4 * q + 3 * q * q) * np.cos(2 * t)
    stt = s0 / 2 * (1 + q) - s0 / 2 * (1 + 3 * q * q) * np.cos(2 * t)
    srt = -s0 / 2 * (1 + 2 * q - 3 * q * q) * np.sin(2 * t)
    c, s = np.cos(t), np.sin(t)
    Q = np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)
    polar = np.stack([np.stack([srr, srt], -1), np.stack([srt, stt], -1)], -2)
    return Q @ polar @ Q.transpose(0, 2, 1)


def boundary_stretch(mesh, u, shape):
    """Nodes on the curve of ``shape`` and the small-strain stretch t . du/ds of the boundary there,
    from the displacement trace on each boundary facet (``line3``), averaged over the facets."""
    on = jf.curve_nodes(mesh, shape)
    f = mesh.boundary_facets()
    f = f[np.isin(f, on).all(axis=1)]
    dN = jf.get_element(mesh.el.facet).shape_grad(np.array([[-1.0], [1.0], [0.0]]))[..., 0]  # at its nodes
    dx = np.einsum("pk,fki->fpi", dN, mesh.nodes[f])
    du = np.einsum("pk,fki->fpi", dN, np.asarray(u)[f])
    stretch = (dx * du).sum(-1) / (dx * dx).sum(-1)
    total = np.bincount(f.ravel(), stretch.ravel(), mesh.n_nodes)
    count = np.bincount(f.ravel(), minlength=mesh.n_nodes)
    return on, total[on] / count[on]


def kirsch_plate(h, law):
    """Solve the truncated Kirsch problem; return the hole's node angles, the hoop stress / s0
    there, the value at the top point, and u."""
    hole = jf.Ellipse(0.0, 0.0, R, R, angle=np.pi / 2)  # the curve's first node is the top point
    mesh = jf.plate(-HALF, -HALF, HALF, HALF, h, holes=[hole], element="tri6")
    facets, loads = [], []
    for side, n in {"left": [-1, 0], "right": [1, 0], "bottom": [0, -1], "top": [0, 1]}.items():
        f = mesh.side_facets(side)
        facets.append(f)
        loads.append(kirsch_stress(mesh.nodes[f].mean(axis=1), S0) @ np.array(n, float))
    near = lambda p: int(np.argmin(np.linalg.norm(mesh.nodes - p, axis=1)))  # noqa: E731
    fixed = np.concatenate([jf.dofs(mesh, near([-HALF, 0])), jf.dofs(mesh, near([HALF, 0]), 1)])
    problem = jf.Problem(mesh, law, "plane-stress", fixed=fixed, traction_facets=np.concatenate(facets))
    solver = jf.Solver(problem)
    theta = problem.params(E=E, nu=NU, traction=np.concatenate(loads))
    u = np.asarray(solver.solve(theta).u)
    # the load is self-equilibrated: the two pins carry (almost) nothing
    assert np.abs(np.asarray(jax.jit(solver.reactions)(u, theta))).max() < 1e-6 * S0 * HALF
    nodes, stretch = boundary_stretch(mesh, u, hole)
    angle = np.arctan2(mesh.nodes[nodes, 1], mesh.nodes[nodes, 0])
    hoop = E * stretch / S0
    top = np.flatnonzero(np.linalg.norm(mesh.nodes[nodes] - [0.0, R], axis=1) < 1e-12)
    assert len(top) == 1
    return angle, hoop, float(hoop[top[0]]), u


@pytest.mark.parametrize("h, tol_top, tol_rms", [(0.5, 0.04, 0.06),
                                                 pytest.param(0.25, 0.006, 0.015, marks=pytest.mark.slow)])
def test_kirsch_concentration_linear_and_neo_hookean(h, tol_top, tol_rms):
    angle, hoop, top, u_lin = kirsch_plate(h, "linear-elastic")
    assert top == pytest.approx(3.0, rel=tol_top)
    rms = np.sqrt(np.mean((hoop - (1 - 2 * np.cos(2 * angle))) ** 2))
    assert rms < tol_rms
    # neo-Hookean at the same tiny load: the linear field, and the same concentration
    angle_nh, hoop_nh, top_nh, u_nh = kirsch_plate(h, "neo-hookean")
    assert np.abs(u_nh - u_lin).max() < 1e-4 * np.abs(u_lin).max()
    assert top_nh == pytest.approx(top, rel=1e-4)
