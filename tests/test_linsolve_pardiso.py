"""PARDISO with the symbolic analysis reused across matrices of one pattern, and the ``auto`` choice."""

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

import jaxfem as jf
from jaxfem import linsolve

pytest.importorskip("pypardiso")


def _random_symmetric(n, seed, indefinite):
    """A random sparse symmetric matrix (a 2D Laplacian-like pattern plus random couplings)."""
    rng = np.random.default_rng(seed)
    A = sp.random(n, n, density=4.0 / n, random_state=rng) + sp.eye(n)
    A = (A + A.T).tocsr()
    d = np.abs(A).sum(axis=1).A1 + rng.uniform(0.1, 1.0, n)
    if indefinite:
        d = d * rng.choice([-1.0, 1.0], n)
    A = (A + sp.diags(d)).tocsr()
    A.sort_indices()
    return A


def _handle(A):
    U = sp.triu(A).tocsr()
    U.sort_indices()
    return linsolve.PardisoHandle(U.indptr, U.indices), U


@pytest.mark.parametrize("indefinite", [False, True])
def test_analysis_once_then_new_values_solve_exactly(indefinite):
    n = 400
    A = _random_symmetric(n, 3, indefinite)
    h, U = _handle(A)
    rng = np.random.default_rng(7)
    for k in range(3):
        # same pattern, new values (the analysis of the first matrix must serve them all)
        vals = U.data * rng.uniform(0.5, 1.5, U.nnz) if k else U.data
        Uk = sp.csr_matrix((vals, U.indices, U.indptr), shape=(n, n))
        Ak = (Uk + sp.triu(Uk, 1).T).tocsc()
        b = rng.standard_normal(n)
        assert h.factor(vals)
        x = h.solve(b)
        ref = spla.spsolve(Ak, b, use_umfpack=False)
        assert np.linalg.norm(x - ref) <= 1e-9 * np.linalg.norm(ref)
    assert h.analysed and h.factorisations == 3


def test_solver_pardiso_matches_superlu_and_factors_once_per_matrix():
    mesh = jf.rectangle(0, 0, 10, 6, 10, 6)
    fixed = np.concatenate([jf.dofs(mesh, mesh.side("left")), jf.dofs(mesh, mesh.side("right"))])
    pb = jf.Problem(mesh, "neo-hookean", "plane-stress", fixed=fixed)
    theta = pb.params(E=10.0, nu=0.3, u_D=pb.prescribe(lambda X: 0.2 * X * [1.0, 0.0]))
    sp_ = jf.Solver(pb, linear_solver="pardiso")
    su = jf.Solver(pb, linear_solver="superlu")
    a, b = sp_.solve(theta), su.solve(theta)
    assert np.abs(np.asarray(a.u) - np.asarray(b.u)).max() <= 1e-9 * np.abs(np.asarray(b.u)).max()
    handle = sp_._lin.handle
    assert handle.factorisations == int(a.info["iterations"])  # one per linear solve, analysis once
    sp_.solve(theta)
    assert handle.factorisations == 2 * int(a.info["iterations"])


def test_auto_choice_depends_on_dimension_and_what_is_installed(monkeypatch):
    assert linsolve.auto_choice(1_000, 2) == "pardiso"
    assert linsolve.auto_choice(1_000_000, 3) == "pardiso"
    monkeypatch.setattr(linsolve, "available", lambda: ["klu", "superlu", "cg", "dense"])
    assert linsolve.auto_choice(linsolve.AUTO_KLU_MAX_DOFS_2D - 1, 2) == "klu"
    assert linsolve.auto_choice(linsolve.AUTO_KLU_MAX_DOFS_2D, 2) == "superlu"
    assert linsolve.auto_choice(1_000, 3) == "superlu"


def test_unknown_solver_is_a_clear_error():
    pat = jf.assembly.make_pattern(jf.rectangle(0, 0, 1, 1, 2, 2))
    with pytest.raises(ValueError, match="unknown linear solver"):
        linsolve.make_linear_solver("mumps", pat, 2)


def test_cholmod_matches_superlu_and_solves_an_indefinite_matrix():
    pytest.importorskip("sksparse.cholmod", reason="scikit-sparse (CHOLMOD) is not installed")
    import jax.numpy as jnp

    mesh = jf.rectangle(0, 0, 10, 6, 10, 6)
    fixed = np.concatenate([jf.dofs(mesh, mesh.side("left")), jf.dofs(mesh, mesh.side("right"))])
    pb = jf.Problem(mesh, "neo-hookean", "plane-stress", fixed=fixed)
    theta = pb.params(E=10.0, nu=0.3, u_D=pb.prescribe(lambda X: 0.2 * X * [1.0, 0.0]))
    sc, su = jf.Solver(pb, linear_solver="cholmod"), jf.Solver(pb, linear_solver="superlu")
    a, b = sc.solve(theta), su.solve(theta)
    assert np.abs(np.asarray(a.u) - np.asarray(b.u)).max() <= 1e-9 * np.abs(np.asarray(b.u)).max()
    # an indefinite matrix on the same pattern (CHOLMOD's LDL^T, or SuperLU where CHOLMOD refuses)
    pat = sc.pattern
    rng = np.random.default_rng(0)
    vals = np.array(sc._constrained(sc.tangent_values(a.u.reshape(-1), theta)))
    vals[pat.diag[: pat.n_dofs // 2]] *= -1.0
    vals[pat.diag[: pat.n_dofs // 2]] -= 1e3
    A = sp.csr_matrix((vals, pat.cols, pat.indptr), shape=(pat.n_dofs,) * 2)
    assert np.allclose(A.toarray(), A.toarray().T)
    rhs = rng.standard_normal(pat.n_dofs)
    _, solve = linsolve.make_linear_solver("cholmod", pat)
    x = np.asarray(solve(jnp.asarray(vals), jnp.asarray(rhs), sc.arrays))
    assert np.linalg.norm(A @ x - rhs) <= 1e-8 * np.linalg.norm(rhs)
