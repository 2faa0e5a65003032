"""The fibre-reinforced law (jaxfem/materials/fibre_reinforced.py): its fibre energy (tension ramp,
compression share), its symmetries, the implicit derivative of the equilibrium with respect to the
fibre angle and stiffness (Taylor tests, both modes), and its fit as a diagnosis's alternative law
on a hidden fibre-reinforced sheet (data on a finer quadratic mesh plus noise).

The registry's sweeps (tests/test_registries.py) already check the law's stress-free reference
state, its small-strain stiffness and Newton's patch test in every kind.
"""

from __future__ import annotations

from functools import cache

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxfem as jf
from jaxfem.materials import LAWS
from jaxfem.materials.fibre_reinforced import RAMP, fibre_energy

LAW = LAWS["fibre-reinforced"]


def _p(**kw):
    p = {"E": 10.0, "nu": 0.3, **{q.name: q.default for q in LAW.extra}, **kw}
    return {k: jnp.float64(v) for k, v in p.items()}


def test_fibre_energy_is_quadratic_in_tension_and_keeps_its_share_in_compression():
    x = jnp.linspace(-0.3, -1e-6, 7)
    for c in (0.0, 0.4, 1.0):
        np.testing.assert_allclose(jax.vmap(lambda v: fibre_energy(v, c))(x), c * x**2, rtol=1e-14, atol=1e-18)
    # well into tension the fibre is x^2 shifted by the ramp (slack until the ramp is done)
    t = jnp.linspace(2.01 * RAMP, 0.3, 7)
    d2 = jax.vmap(jax.grad(jax.grad(lambda v: fibre_energy(v, 0.0))))(t)
    np.testing.assert_allclose(d2, 2.0, rtol=1e-12)
    # convex everywhere, second derivative continuous through the ramp
    s = jnp.linspace(-0.05, 0.05, 4001)
    second = jax.vmap(jax.grad(jax.grad(lambda v: fibre_energy(v, 0.0))))(s)
    assert float(second.min()) >= 0.0 and float(jnp.abs(jnp.diff(second)).max()) < 0.01


def test_law_without_fibres_is_neo_hookean_and_the_angle_is_a_direction():
    F = jnp.eye(3) + jnp.array([[0.12, 0.05, 0.0], [-0.03, -0.04, 0.0], [0.0, 0.0, -0.02]])
    nh = LAWS["neo-hookean"].energy(F, _p())
    assert abs(float(LAW.energy(F, _p(fibre_stiffness=0.0))) - float(nh)) < 1e-13
    for theta in (0.3, -1.1):
        a, b = (float(LAW.energy(F, _p(fibre_angle=t, fibre_stiffness=3.0))) for t in (theta, theta + np.pi))
        assert abs(a - b) < 1e-12 * abs(a)
    # two mirrored families of equal share: the law is even in the angle
    a, b = (float(LAW.energy(F, _p(fibre_angle=t, fibre_stiffness=3.0, fibre_mirror=0.5))) for t in (0.4, -0.4))
    assert abs(a - b) < 1e-12 * abs(a)


def test_small_strain_stiffness_along_the_fibres_is_matrix_plus_k_E():
    # the uniaxial stiffness along the fibre direction (sigma_aa / eps_aa at fixed other strains)
    theta, k, E = 0.7, 4.0, 10.0
    a = jnp.array([np.cos(theta), np.sin(theta), 0.0])
    C = jax.jit(jax.hessian(LAW.energy))(jnp.eye(3), _p(fibre_angle=theta, fibre_stiffness=k, E=E))
    C0 = jax.jit(jax.hessian(LAWS["neo-hookean"].energy))(jnp.eye(3), _p(E=E))
    along = float(jnp.einsum("ijkl,i,j,k,l->", C - C0, a, a, a, a))
    assert abs(along - k * E) < 1e-10 * k * E
    b = jnp.array([-np.sin(theta), np.cos(theta), 0.0])  # across the fibres: the matrix alone
    assert abs(float(jnp.einsum("ijkl,i,j,k,l->", C - C0, b, b, b, b))) < 1e-10 * E


# ---------------------------------------------------------------- implicit derivatives
H0, STEPS, MIN_RATE = 1e-2, 5, 1.8


@cache
def _case():
    """A plane-stress plate with a hole, fibres at 0.5 rad keeping 40 % of their stiffness in
    compression (the ramp is crossed near the hole), pulled 10 % and sheared; misfit 0.5 |u - m|^2."""
    mesh = jf.plate(0, 0, 20, 12, 2.0, holes=[jf.Ellipse(10, 6, 3, 2, 0.2)])
    fixed = np.concatenate([jf.dofs(mesh, mesh.side("left")), jf.dofs(mesh, mesh.side("right"))])
    problem = jf.Problem(mesh, "fibre-reinforced", "plane-stress", fixed=fixed)
    pull = problem.prescribe(lambda X: 0.1 * X[:, :1] * np.array([1.0, 0.3]))
    theta = problem.params(E=10.0, nu=0.3, u_D=pull, fibre_angle=0.5, fibre_stiffness=3.0, fibre_compression=0.4)
    solver = jf.Solver(problem)
    target = np.asarray(solver.displacement(theta)) + 0.3 * np.random.default_rng(2).normal(size=(mesh.n_nodes, 2))
    misfit = lambda th: 0.5 * jnp.sum((solver.displacement(th) - target) ** 2)  # noqa: E731
    jvp = jax.jit(lambda th, v: jax.jvp(misfit, (th,), (v,)))
    return theta, jax.jit(jax.value_and_grad(misfit)), jvp


@pytest.mark.parametrize("mode", ["reverse", pytest.param("forward", marks=pytest.mark.slow)])
@pytest.mark.parametrize("key, scale", [("fibre_angle", 0.2), ("fibre_stiffness", 1.0)])
def test_taylor_rate_is_two_for_the_fibre_angle_and_stiffness(key, scale, mode):
    theta, value_and_grad, jvp = _case()
    d = jax.tree.map(jnp.zeros_like, theta)
    d[key] = jnp.asarray(scale * np.random.default_rng(len(key)).normal(size=theta[key].shape))
    if mode == "reverse":
        f = jax.custom_vjp(lambda x: value_and_grad(x)[0])
        f.defvjp(value_and_grad, lambda g, ct: (jax.tree.map(lambda a: ct * a, g),))
    else:
        f = jax.custom_jvp(lambda x: value_and_grad(x)[0])
        f.defjvp(lambda primals, tangents: jvp(primals[0], tangents[0]))
    result = jf.taylor_test(f, theta, d, h0=H0, steps=STEPS, mode=mode)
    assert result.min_rate > MIN_RATE, f"{key} {mode}\n{result}"
