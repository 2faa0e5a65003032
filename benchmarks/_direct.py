"""Sparse direct solvers of benchmarks/forward.py, each timed alone on jaxfem's tangent.

:func:`direct_solvers`: one factor + solve of a given matrix by each sparse direct solver that is
installed here (SciPy SuperLU twice, KLU via klujax, MKL PARDISO via pypardiso, CHOLMOD via
scikit-sparse), every one timed from the CSR values array to the solution, best of N;
:func:`phase_split`: symbolic analysis, numeric factorisation and solve timed apart (PARDISO,
CHOLMOD); :func:`pardiso_construction_seconds`: what constructing a pypardiso solver costs.
"""

from __future__ import annotations

import glob
import os
import sys
import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from benchmarks._timing import best_of, loadavg


def mkl_rt_path() -> str | None:
    """Path of MKL's runtime library as pypardiso finds it (its own recursive glob of sys.prefix)."""
    hits = sorted(glob.glob(f"{sys.prefix}/[Ll]ib*/**/*mkl_rt*", recursive=True), key=len)
    return hits[0] if hits else None


def pardiso_construction_seconds(repeats=3) -> dict:
    """Cost of ``pypardiso.PyPardisoSolver()`` with and without PYPARDISO_MKL_RT set (jaxfem makes one
    per linear solve; without the variable each construction globs the whole virtualenv)."""
    import pypardiso

    old = os.environ.pop("PYPARDISO_MKL_RT", None)
    try:
        without, _, _ = best_of(pypardiso.PyPardisoSolver, repeats)
        os.environ["PYPARDISO_MKL_RT"] = mkl_rt_path() or ""
        with_env, _, _ = best_of(pypardiso.PyPardisoSolver, repeats)
    finally:
        os.environ.pop("PYPARDISO_MKL_RT", None)
        if old is not None:
            os.environ["PYPARDISO_MKL_RT"] = old
    n_files = sum(len(f) for _, _, f in os.walk(sys.prefix))
    return {"seconds_without_PYPARDISO_MKL_RT": without, "seconds_with_PYPARDISO_MKL_RT": with_env,
            "files_under_sys_prefix": n_files}


def available_direct() -> list[str]:
    names = ["superlu_colamd", "superlu_jaxfem"]
    for mod, name in (("klujax", "klu"), ("pypardiso", "pardiso_jaxfem"), ("pypardiso", "pardiso_spd"),
                      ("sksparse.cholmod", "cholmod")):
        try:
            __import__(mod)
            names.append(name)
        except ImportError:
            pass
    return names


def _upper(indptr, cols, n):
    rows = np.repeat(np.arange(n), np.diff(indptr))
    keep = np.flatnonzero(cols >= rows)
    up_ptr = np.zeros(n + 1, np.int64)
    np.add.at(up_ptr, rows[keep] + 1, 1)
    return keep, cols[keep], np.cumsum(up_ptr)


def make_direct(name: str, indptr, cols, rows):
    """A function ``(vals, b) -> x`` for one solver on a fixed CSR pattern (symmetric matrix).

    Everything that depends on the values (format conversion, ordering, factorisation, solve) is
    inside the function; what depends on the pattern alone is done here once, as a solver would.
    """
    n = len(indptr) - 1
    indptr = np.asarray(indptr, np.int64)
    cols = np.asarray(cols, np.int32)
    if name == "superlu_colamd":  # what scipy.sparse.linalg.spsolve does by default (no UMFPACK)
        def solve(vals, b):
            A = sp.csr_matrix((vals, cols, indptr), shape=(n, n))
            return spla.spsolve(A.tocsc(), b, use_umfpack=False)
        return solve
    if name == "superlu_jaxfem":  # jaxfem.linsolve.superlu: symmetric mode, MMD on A^T + A
        def solve(vals, b):
            A = sp.csr_matrix((vals, cols, indptr), shape=(n, n)).tocsc()
            lu = spla.splu(A, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                           options={"SymmetricMode": True})
            return lu.solve(b)
        return solve
    if name == "klu":
        import jax
        import jax.numpy as jnp
        import klujax

        r, c = jnp.asarray(rows, jnp.int32), jnp.asarray(cols, jnp.int32)
        f = jax.jit(klujax.solve)

        def solve(vals, b):
            return np.asarray(jax.block_until_ready(f(r, c, jnp.asarray(vals), jnp.asarray(b))))
        return solve
    if name in ("pardiso_jaxfem", "pardiso_spd"):
        import pypardiso

        keep, ucols, uptr = _upper(indptr, cols, n)

        def solve(vals, b):
            A = sp.csr_matrix((vals[keep], ucols, uptr), shape=(n, n))
            A.has_sorted_indices = True
            s = pypardiso.PyPardisoSolver(mtype=-2 if name == "pardiso_jaxfem" else 2)
            if name == "pardiso_jaxfem":  # the iparm settings of jaxfem.linsolve.pardiso
                s.set_iparm(1, 1)
                s.set_iparm(2, 2)
                s.set_iparm(10, 8)
                s.set_iparm(11, 0)
                s.set_iparm(13, 0)
            try:
                return s.solve(A, b)
            finally:
                s.free_memory(everything=True)
        return solve
    if name == "cholmod":
        from sksparse.cholmod import cholesky

        def solve(vals, b):
            # a symmetric matrix's CSR arrays are its CSC arrays: no conversion needed
            A = sp.csc_matrix((vals, cols, indptr), shape=(n, n))
            return cholesky(A)(b)
        return solve
    raise ValueError(name)


def phase_split(name: str, indptr, cols, vals, b) -> dict:
    """Seconds of the symbolic analysis vs numeric factorisation vs solve (PARDISO, CHOLMOD): what
    reusing the analysis across Newton iterations would save."""
    n = len(indptr) - 1
    out = {}
    os.environ["PYPARDISO_MKL_RT"] = mkl_rt_path() or ""
    if name == "pardiso":
        import pypardiso

        keep, ucols, uptr = _upper(np.asarray(indptr), np.asarray(cols), n)
        A = sp.csr_matrix((vals[keep], ucols, uptr), shape=(n, n))
        A.has_sorted_indices = True
        best = {}
        for _ in range(2):
            s = pypardiso.PyPardisoSolver(mtype=-2)
            for k, v in ((1, 1), (2, 2), (10, 8), (11, 0), (13, 0)):
                s.set_iparm(k, v)
            for phase in (11, 22, 33):
                s.set_phase(phase)
                t = time.perf_counter()
                s._call_pardiso(A, b)
                best[phase] = min(best.get(phase, 1e99), time.perf_counter() - t)
            s.free_memory(everything=True)
        out = {"analyse": best[11], "factor": best[22], "solve": best[33]}
    elif name == "cholmod":
        from sksparse.cholmod import analyze

        A = sp.csc_matrix((vals, cols, indptr), shape=(n, n))
        ta, _, fac = best_of(lambda: analyze(A), 2)
        tf, _, _ = best_of(lambda: fac.cholesky_inplace(A), 2)
        ts, _, _ = best_of(lambda: fac(b), 2)
        out = {"analyse": ta, "factor": tf, "solve": ts}
    os.environ.pop("PYPARDISO_MKL_RT", None)
    return out


def direct_solvers(indptr, cols, rows, vals, b, names=None, repeats=3, skip=None, budget=60.0) -> dict:
    """Best-of-``repeats`` seconds of one factor + solve by each solver, with its relative residual.

    ``skip``: ``name -> predicted seconds``; a solver predicted over ``budget`` is not run.
    """
    n = len(indptr) - 1
    A = sp.csr_matrix((vals, cols, indptr), shape=(n, n))
    res = {}
    # time PARDISO's factor + solve, not pypardiso's search for libmkl_rt (see pardiso_construction_seconds)
    old = os.environ.get("PYPARDISO_MKL_RT")
    os.environ["PYPARDISO_MKL_RT"] = mkl_rt_path() or ""
    try:
        return _direct_solvers(A, indptr, cols, rows, vals, b, names, repeats, skip, budget, res)
    finally:
        os.environ.pop("PYPARDISO_MKL_RT", None)
        if old is not None:
            os.environ["PYPARDISO_MKL_RT"] = old


def _direct_solvers(A, indptr, cols, rows, vals, b, names, repeats, skip, budget, res):
    for name in names or available_direct():
        pred = (skip or {}).get(name)
        if pred is not None and pred > budget:
            res[name] = {"skipped": f"predicted {pred:.0f} s > {budget:.0f} s"}
            continue
        try:
            fn = make_direct(name, indptr, cols, rows)
            if name == "klu":
                fn(vals, b)  # compile the jitted call once
            t, times, x = best_of(lambda: fn(vals, b), repeats, budget=budget)
            rel = float(np.linalg.norm(A @ x - b) / np.linalg.norm(b))
            res[name] = {"seconds": t, "all": times, "rel_residual": rel, "load": loadavg()}
        except Exception as e:  # noqa: BLE001 - record why a solver failed, keep going
            res[name] = {"error": f"{type(e).__name__}: {e}"[:300]}
    return res

