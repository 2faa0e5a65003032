"""Traction-loaded facets padded to a bucket inside jaxfem (jaxfem.padding): copies of a real
facet under a zero facet mask, so meshes with other counts of loaded facets (a hole cut through a
loaded face, a remesh) share one compiled solve, and the copies add no force and no derivative,
whatever the traction (per facet, or one uniform vector). Small sheets and boxes; which facets are
loaded, how many, and the loads drawn under a seed."""

from functools import partial

import jax
import numpy as np
import pytest

import jaxfem as jf
from jaxfem import padding
from jaxfem.newton import external_force
from tests.test_shared_programs import COMPILES, real_size_solver

# Saint Venant-Kirchhoff under plane strain: a program no other test of this process pads for,
# so the padded sizes a solver is given depend on this file's solvers alone
LAW_2D, KIN_2D = "saint-venant-kirchhoff", "plane-strain"


def _loaded(mesh, sides, n, rng):
    """``n`` facets drawn from the mesh's ``sides`` (in a random order)."""
    facets = np.concatenate([mesh.side_facets(s) for s in sides])
    return facets[rng.permutation(len(facets))[:n]]


def _sheet(nx, ny, n_loaded, rng, law=LAW_2D, kinematics=KIN_2D):
    mesh = jf.rectangle(0, 0, 100, 60, nx, ny)
    fixed = jf.dofs(mesh, mesh.side("left"))
    return jf.Problem(mesh, law, kinematics, fixed=fixed,
                      traction_facets=_loaded(mesh, ("right", "top", "bottom"), n_loaded, rng))


def _box(n_loaded, rng):
    mesh = jf.box(0, 0, 0, 3, 2, 2, 3, 2, 2, "tet4")
    fixed = jf.dofs(mesh, mesh.side("left"))
    return jf.Problem(mesh, "neo-hookean", "solid", fixed=fixed,
                      traction_facets=_loaded(mesh, ("right", "top"), n_loaded, rng))


def _problem(dim, rng):
    if dim == 2:
        return _sheet(int(rng.integers(4, 7)), int(rng.integers(3, 5)), int(rng.integers(3, 14)), rng)
    return _box(int(rng.integers(3, 14)), rng)


def _force_and_derivatives(fe, X, t, g, arrays):
    """The external force of the traction ``t`` on ``arrays``' facets and the cotangents of ``X``
    and ``t`` of ``g`` (on the first dofs): the whole derivative, one random combination of its
    rows."""
    n_all = X.shape[0] * X.shape[1]
    f, vjp = jax.vjp(lambda X, t: external_force({"X": X}, {"f": 0.0, "traction": t}, arrays, fe, n_all), X, t)
    return f, vjp(jax.numpy.pad(g, (0, n_all - g.size)))


@partial(jax.jit, static_argnums=0)
def _forces(fe, *cases):
    """:func:`_force_and_derivatives` of each case (one program for all of them)."""
    return [_force_and_derivatives(fe, *c) for c in cases]


@pytest.mark.parametrize("dim", [pytest.param(2, marks=pytest.mark.slow), 3])  # 1.3-1.5 s each (a compile)
def test_padding_facets_add_no_force_and_no_derivative(dim):
    """The external force on the padded arrays (facets padded with copies of a real one, a per-facet
    traction with zeros, a uniform one masked) and its derivative along a random cotangent in the
    coordinates and the traction (the cotangents of both), are those of the real facets alone
    (no solve: the force alone, cheap)."""
    rng = np.random.default_rng(100 + dim)
    problem = _problem(dim, rng)
    solver = jf.Solver(problem, "superlu")
    s, n = solver.sizes, problem.n_dofs
    assert 0 < s.n_facets < s.n_facets_p and solver.padded_arrays["tfacets"].shape[0] == s.n_facets_p
    X = np.asarray(problem.mesh.nodes)
    t, g = rng.normal(size=(s.n_facets, dim)), rng.normal(size=n)
    th_p = padding.pad_theta({"X": X, "traction": t}, s)
    assert th_p["traction"].shape == (s.n_facets_p, dim) and not th_p["traction"][s.n_facets:].any()
    t0 = rng.normal(size=dim)  # one uniform traction (dim,)
    real, padded, uniform, broadcast = _forces(
        problem.mesh.el.facet, (X, t, g, solver.arrays), (th_p["X"], th_p["traction"], g, solver.padded_arrays),
        (th_p["X"], t0, g, solver.padded_arrays), (X, np.tile(t0, (s.n_facets, 1)), g, solver.arrays))
    f, (gX, gt) = real
    assert np.abs(f).max() > 0.1 * np.abs(t).max() and np.abs(gX).max() > 0.1  # the facets are loaded
    f_p, (gX_p, gt_p) = padded
    got = padding.unpad_theta({"X": gX_p, "traction": gt_p}, s)
    assert np.isfinite(gX_p).all() and np.isfinite(gt_p).all()
    np.testing.assert_allclose(f_p[:n], f, rtol=0, atol=1e-13)
    assert not np.asarray(f_p[n:]).any() and not np.asarray(gt_p[s.n_facets:]).any()
    np.testing.assert_allclose(got["X"], gX, rtol=0, atol=1e-12)
    np.testing.assert_allclose(got["traction"], gt, rtol=0, atol=1e-12)
    # the uniform traction loads the real facets only (the copies are masked)
    (f_u, (gX_u, gt_u)), (f_b, (gX_b, gt_b)) = uniform, broadcast
    assert np.isfinite(gX_u).all() and np.isfinite(gt_u).all()
    np.testing.assert_allclose(f_u[:n], f_b, rtol=0, atol=1e-13)
    np.testing.assert_allclose(gX_u[: problem.mesh.n_nodes], gX_b, rtol=0, atol=1e-12)
    np.testing.assert_allclose(gt_u, gt_b.sum(0), rtol=0, atol=1e-12)


def test_other_loaded_facet_counts_of_one_bucket_get_one_padded_shape():
    """Two sheets of other meshes and other counts of loaded facets (drawn) in one bucket: the
    same padded sizes, and every argument of the solve (parameters, start, loads, arrays) the same
    shape, so one compiled program serves both; a count beyond the bucket gets a larger one (it
    does not fit), and a problem without traction facets keeps none. Constructing solvers and
    padding arguments compiles nothing (cheap)."""
    rng = np.random.default_rng(41)
    n1, n2 = rng.choice(np.arange(3, 16), 2, replace=False)
    a, b = _sheet(10, 6, int(n1), rng), _sheet(9, 7, int(n2), rng)
    sa, sb = jf.Solver(a, "superlu"), jf.Solver(b, "superlu")
    assert sa.program is sb.program and sa.sizes.n_facets != sb.sizes.n_facets
    assert sa.sizes.n_facets_p == sb.sizes.n_facets_p == padding.bucket(max(n1, n2))

    def shapes(solver):
        p = solver.problem
        theta = p.params(E=rng.uniform(50, 100, p.mesh.n_cells), traction=rng.normal(size=(p.traction_facets.shape[0], 2)))
        args = (solver._pad(theta, *solver._start(theta, None)), solver.padded_arrays)
        return jax.tree.structure(args), [(np.shape(v), np.asarray(v).dtype) for v in jax.tree.leaves(args)]

    assert shapes(sa) == shapes(sb)
    mask = np.asarray(sb.padded_arrays["facet_mask"])
    assert mask.sum() == n2 and mask[:n2].all()
    np.testing.assert_array_equal(sb.padded_arrays["tfacets"][n2:], np.repeat(b.traction_facets[:1], len(mask) - n2, 0))
    # more facets than the bucket holds, on a coarser mesh: the sheets' mesh padding, its own facets'
    more = _sheet(8, 5, int(sa.sizes.n_facets_p) + 1, rng)
    sm = jf.Solver(more, "superlu")
    assert not padding.fits(sm.sizes, sa.sizes) and sm.sizes.n_facets_p == padding.bucket(sm.sizes.n_facets)
    assert (sm.sizes.n_cells_p, sm.sizes.nnz_p, sm.sizes.n_nodes_p) == (sa.sizes.n_cells_p, sa.sizes.nnz_p,
                                                                        sa.sizes.n_nodes_p)
    none = jf.Solver(jf.Problem(a.mesh, LAW_2D, KIN_2D, fixed=a.fixed), "superlu")
    assert none.sizes.n_facets_p == 0 and none.padded_arrays["tfacets"].shape[0] == 0
    assert not padding.fits(none.sizes, sa.sizes) and not padding.fits(sa.sizes, none.sizes)


@pytest.mark.slow  # four solves' programs compiled (Newton, tangents, adjoint at two sizes): ~40 CPU s
@pytest.mark.parametrize("dim", [2, 3])
def test_padded_facets_solve_as_the_real_sizes_with_the_same_derivatives(dim):
    """A traction-loaded problem solved padded (facets to their bucket) equals the same problem at
    its real sizes, for a per-facet and a uniform traction, and so do its tangents along random
    directions of the traction and the coordinates and its adjoint gradient (finite, the uniform
    traction's the sum of the per-facet one's over the real facets)."""
    rng = np.random.default_rng(200 + dim)
    problem = _problem(dim, rng)
    padded, ref = jf.Solver(problem, "superlu"), real_size_solver(problem)
    assert padded.sizes.n_facets_p > padded.sizes.n_facets and ref.sizes.n_facets_p == ref.sizes.n_facets
    nf = padded.sizes.n_facets
    scale = 0.05 if dim == 2 else 0.5
    t0 = scale * rng.normal(size=dim)
    per_facet = problem.params(E=10.0, nu=0.3, traction=t0 + 0.3 * scale * rng.normal(size=(nf, dim)))
    uniform = {**problem.params(E=10.0, nu=0.3), "traction": t0}
    free = problem.free_mask.reshape(-1, dim).astype(float)
    d = {k: np.zeros((3,) + np.shape(v)) for k, v in per_facet.items()}
    d["traction"] = scale * rng.normal(size=d["traction"].shape)
    d["X"] = 0.05 * rng.normal(size=d["X"].shape) * free
    g = rng.normal(size=problem.mesh.nodes.shape)
    for theta in (per_facet, uniform):
        dirs = d if np.ndim(theta["traction"]) == 2 else {**d, "traction": d["traction"][:, 0]}
        u, du, _ = padded.solve_with_tangents(theta, dirs)
        u_ref, du_ref, _ = ref.solve_with_tangents(theta, dirs)
        assert np.abs(u_ref).max() > 1e-2 and np.abs(du_ref).max() > 1e-3
        np.testing.assert_allclose(u, u_ref, rtol=0, atol=1e-10 * np.abs(u_ref).max())
        np.testing.assert_allclose(du, du_ref, rtol=0, atol=1e-9 * np.abs(du_ref).max())
        grad = padded.adjoint(padded.solve_for_adjoint(theta)[1], g)
        want = ref.adjoint(ref.solve_for_adjoint(theta)[1], g)
        for k in ("traction", "X", "E"):
            assert np.shape(grad[k]) == np.shape(theta[k]) and np.isfinite(grad[k]).all()
            np.testing.assert_allclose(grad[k], want[k], rtol=0, atol=1e-9 * np.abs(want[k]).max())
    # a uniform traction loads every real facet alike: the per-facet solve of its broadcast
    same = padded.solve({**per_facet, "traction": np.tile(t0, (nf, 1))}).u
    np.testing.assert_allclose(padded.solve(uniform).u, same, rtol=0, atol=1e-12 * np.abs(same).max())
    g_facets = padded.adjoint(padded.solve_for_adjoint({**per_facet, "traction": np.tile(t0, (nf, 1))})[1], g)
    np.testing.assert_allclose(padded.adjoint(padded.solve_for_adjoint(uniform)[1], g)["traction"],
                               g_facets["traction"].sum(0), rtol=0, atol=1e-10 * np.abs(g_facets["traction"]).max())


@pytest.mark.slow  # the first sheet's Newton, tangents and adjoint compiled: ~15 CPU s
def test_other_loaded_facet_counts_of_one_bucket_compile_the_solve_once():
    """Two sheets of other meshes and other counts of loaded facets (drawn) in one bucket: the
    second one's solve, tangents and adjoint compile nothing, and its solve is an equilibrium of its
    real facets' loads (the free residual at its real sizes, no padding, vanishes)."""
    rng = np.random.default_rng(43)
    n1, n2 = rng.choice(np.arange(3, 16), 2, replace=False)
    a, b = _sheet(10, 6, int(n1), rng, "neo-hookean"), _sheet(9, 7, int(n2), rng, "neo-hookean")
    sa, sb = jf.Solver(a, "superlu"), jf.Solver(b, "superlu")
    assert sa.sizes.n_facets != sb.sizes.n_facets and sa.sizes.n_facets_p == sb.sizes.n_facets_p

    def loads(solver):  # (its broadcasts compile small programs per mesh: not the solve's)
        p = solver.problem
        theta = p.params(E=rng.uniform(50, 100, p.mesh.n_cells), traction=rng.normal(0, 2.0, (solver.sizes.n_facets, 2)))
        dirs = {k: np.zeros((2,) + np.shape(v)) for k, v in theta.items()}
        dirs["traction"] = rng.normal(size=dirs["traction"].shape)
        return theta, dirs

    def run(solver, theta, dirs):
        u, du, _ = solver.solve_with_tangents(theta, dirs)
        return u, du, solver.adjoint(solver.solve_for_adjoint(theta)[1], np.ones(u.shape))

    run(sa, *loads(sa))
    theta, dirs = loads(sb)
    with COMPILES as c:
        u, du, grad = run(sb, theta, dirs)
    assert c.n == 0, f"the second count of loaded facets compiled {c.n} programs"
    assert np.isfinite(du).all() and np.isfinite(grad["traction"]).all() and np.abs(u).max() > 0.1
    r = np.asarray(sb.residual(u, theta))[b.free_mask]
    assert np.abs(r).max() < 1e-8 * np.abs(theta["traction"]).max()
