"""The equilibrium's Taylor series along a parameter path (jaxfem.series) and the Pade
approximants built on it (refine.optimize.pade).

The series is checked against forward solves at points along the path: the remainder of the
series truncated at order K must shrink like h^(K+1) (a Taylor test of every order at once), and
the full series must match the solves to rounding where it converges.
"""

from __future__ import annotations

import numpy as np
import pytest

import jaxfem as jf
from jaxfem.series import equilibrium_series
from refine.optimize.pade import VectorPade, pade_minimiser


def _strip(kind: str, element: str, seed: int, n=(8, 5)):
    """A 100 x 60 strip pulled and sheared by its ends, with a random rectangular region."""
    rng = np.random.default_rng(seed)
    mesh = jf.rectangle(0, 0, 100, 60, *n, element)
    fixed = np.concatenate([jf.dofs(mesh, mesh.side("left")), jf.dofs(mesh, mesh.side("right"))])
    problem = jf.Problem(mesh, "neo-hookean", kind, fixed=fixed)
    solver = jf.Solver(problem)
    c = mesh.nodes[mesh.cells].mean(axis=1)
    cx, cy = rng.uniform(30, 70), rng.uniform(20, 40)
    inside = (np.abs(c[:, 0] - cx) < rng.uniform(10, 20)) & (np.abs(c[:, 1] - cy) < rng.uniform(8, 14))
    stretch, shear = rng.uniform(0.1, 0.2), rng.uniform(-0.05, 0.05)
    u_D = problem.prescribe(lambda X: np.c_[stretch * X[:, 0], shear * X[:, 0]])
    return problem, solver, inside, u_D


@pytest.mark.parametrize("kind, element, key", [("plane-stress", "tri6", "E"), ("plane-strain", "quad4", "nu")])
def test_series_matches_forward_solves_along_the_path(kind, element, key):
    problem, solver, inside, u_D = _strip(kind, element, seed=3)
    rng = np.random.default_rng(4)
    if key == "E":  # a region's modulus ratio: E = 50 (1 + (rho - 1) inside)
        rho0, base = rng.uniform(1.5, 4.0), 50.0

        def theta(rho):
            return problem.params(E=np.where(inside, base * rho, base), nu=0.3, u_D=u_D)

        direction = np.where(inside, base, 0.0)
    else:  # Poisson's ratio everywhere
        rho0 = rng.uniform(0.2, 0.35)

        def theta(rho):
            return problem.params(E=50.0, nu=rho, u_D=u_D)

        direction = np.ones(problem.mesh.n_cells)
    order = 8
    path = {key: np.zeros((order, problem.mesh.n_cells))}
    path[key][0] = direction  # an affine path
    th0 = theta(rho0)
    u0 = np.asarray(solver.solve(th0).u)
    U = np.asarray(equilibrium_series(solver, u0, th0, path, order))
    assert U.shape == (order, problem.mesh.n_nodes, 2)
    assert np.all(U.reshape(order, -1)[:, problem.fixed] == 0.0)  # the prescribed dofs do not move
    hs = (0.04, 0.02) if key == "E" else (0.02, 0.01)
    exact = {h: np.asarray(solver.solve(theta(rho0 + h)).u) for h in hs}

    def remainder(K, h):
        return np.abs(u0 + sum(U[j] * h ** (j + 1) for j in range(K)) - exact[h]).max()

    for K in (1, 2, 3):  # the remainder of order K shrinks like h^(K+1)
        rate = np.log2(remainder(K, hs[0]) / remainder(K, hs[1]))
        assert rate == pytest.approx(K + 1, abs=0.3), (K, rate)
    assert remainder(order, hs[1]) < 1e-10 * np.abs(exact[hs[1]]).max()


def test_series_refuses_what_it_cannot_do():
    problem, solver, inside, u_D = _strip("plane-stress", "tri3", seed=0)
    th = problem.params(E=50.0, nu=0.3, u_D=u_D)
    u0 = solver.solve(th).u
    with pytest.raises(ValueError, match="cannot move"):
        equilibrium_series(solver, u0, th, {"u_D": np.zeros((2, len(u_D)))}, 2)
    with pytest.raises(ValueError, match="shape"):
        equilibrium_series(solver, u0, th, {"E": np.zeros((3, problem.mesh.n_cells))}, 2)
    with pytest.raises(ValueError, match="not an equilibrium"):
        equilibrium_series(solver, 0.5 * np.asarray(u0), th, {"E": np.zeros((2, problem.mesh.n_cells))}, 2)
    with pytest.raises(ValueError, match="positive integer"):
        equilibrium_series(solver, u0, th, {}, 0)


def test_vector_pade_continues_a_rational_function_past_the_series_radius():
    rng = np.random.default_rng(7)
    pole = -rng.uniform(0.3, 0.6)  # the series of a / (1 - t / pole) + b + c t converges for |t| < |pole|
    a, b, c = rng.standard_normal((3, 5))
    C = np.array([a + b, a / pole + c] + [a / pole ** k for k in range(2, 9)])
    t = 10.0 * abs(pole)  # far outside the radius: the truncated series is useless there
    exact = a / (1.0 - t / pole) + b + c * t
    assert np.abs(sum(C[k] * t ** k for k in range(9)) - exact).max() > 1e3
    f = VectorPade(C, 2, 1)  # numerator degree 2 holds b + c t over the shared denominator
    np.testing.assert_allclose(f(t), exact, rtol=1e-9)
    assert f.pole_free(-5.0, 5.0)[0] == pytest.approx(pole, rel=1e-9)
    # the minimiser of |f|^2 is found within the pole-free interval
    t_min, value = pade_minimiser(C, 2, 1, -5.0, 5.0)
    ts = np.linspace(pole * 0.999, 5.0, 20001)
    assert value <= 0.5 * np.sum(f(ts) ** 2, axis=-1).min() + 1e-12
    assert pole < t_min <= 5.0


@pytest.mark.parametrize("order", [2, pytest.param(3, marks=pytest.mark.slow)])
def test_series_agrees_with_nested_implicit_derivatives(order):
    """Two independent routes to the same derivatives: the series' u_k times k! against k nested
    forward-mode derivatives of Solver.displacement (the implicit function theorem at every level).
    The third order, where the tangent matrix's own derivative enters twice, compiles for ~2 min
    (slow); the second is where it enters first."""
    import jax
    import jax.numpy as jnp

    problem, solver, inside, u_D = _strip("plane-stress", "tri3", seed=5, n=(5, 3))
    E0, rho0 = 50.0, np.random.default_rng(6).uniform(2.0, 5.0)
    direction = np.where(inside, E0, 0.0)
    base = problem.params(E=np.where(inside, E0 * rho0, E0), nu=0.3, u_D=u_D)

    def u(t):
        return solver.displacement({**base, "E": base["E"] + t * direction})

    def derivative(f):
        return lambda t: jax.jvp(f, (t,), (jnp.ones_like(t),))[1]

    d1 = derivative(u)
    d2 = derivative(d1)
    d3 = derivative(d2)  # traced only where order 3 asks for it
    t0 = jnp.asarray(0.0)
    path = {"E": np.zeros((order, problem.mesh.n_cells))}
    path["E"][0] = direction
    U = np.asarray(equilibrium_series(solver, u(t0), base, path, order))
    for k, (d, factorial) in enumerate(((d1, 1.0), (d2, 2.0), (d3, 6.0))[:order]):
        np.testing.assert_allclose(np.asarray(d(t0)), factorial * U[k], rtol=1e-7,
                                   atol=1e-9 * np.abs(factorial * U[k]).max(), err_msg=f"order {k + 1}")
