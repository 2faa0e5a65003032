"""Newton-Raphson with adaptive load stepping, its loop on the host over small jitted kernels.

The same algorithm as :func:`jaxfem.newton.newton_solve` (read its module doc: the predictor,
the corrections, the back-tracking guard, cut-backs, early abandon, the convergence tests), pass
for pass and decision for decision, with the loop, the load stepping and the linear solves run
in Python: the device programs are the kernels alone (the residual, tangent values and material
state at a point; the external force at a load fraction; the smallest det F), which call nothing
back into Python, so JAX's persistent compilation cache keeps them between processes (a program
with a host callback inside is compiled in every process). A host linear solver factorises and
solves here directly; any other solver's solve is a jitted kernel too.

The outcome is data as in :func:`~jaxfem.newton.newton_solve` (``status``, the counters and the
residual log, host numpy), so :class:`~jaxfem.solver.Solver` reads both alike.
"""

from __future__ import annotations

import os

import numpy as np

from .exceptions import OptionError
from .newton import INVERTED, NAN, NO_CONVERGENCE, OK, SINGULAR, NewtonOptions

PREDICT, CORRECT = 0, 1

#: the environment variable that picks where Newton's loop runs: ``host`` (default: this module)
#: or ``jit`` (the whole solve one jitted program, :func:`jaxfem.newton.newton_solve`, whose host
#: linear solver is a callback: compiled in every process)
NEWTON_ENV = "NONRIGID_NEWTON"


def loop_on_host() -> bool:
    """Whether solvers made now run Newton's loop on the host (see :data:`NEWTON_ENV`)."""
    v = os.environ.get(NEWTON_ENV, "host").strip().lower() or "host"
    if v not in ("host", "jit"):
        raise OptionError(f"{NEWTON_ENV} must be 'host' or 'jit', not {v!r}")
    return v == "host"


def _norm(x) -> float:
    return float(np.sqrt(np.dot(x, x)))


def host_newton(kernels, theta, u0, loads0, arrays, host: dict, opts: NewtonOptions, finite: bool):
    """Solve R(u; theta) = f_ext(theta) from the equilibrium ``u0`` of the loads ``loads0``.

    Args:
        kernels: the program's kernels: ``evaluate(theta, u, lam, arrays) -> (R_int, vals, lam)``,
            ``external(theta, loads0, s, arrays) -> f_ext`` at load fraction ``s``,
            ``min_det(theta, u, arrays) -> float``, ``n_qp`` (quadrature points per cell) and
            ``solve(K, rhs) -> x`` (the constrained matrix's solve, on the host).
        theta, u0, loads0, arrays: as :func:`jaxfem.newton.newton_solve` (padded).
        host: host numpy copies of ``arrays``' ``rows``, ``cols``, ``fixed``, ``free``, ``keep``,
            ``diag_fixed`` and ``n_cells``.
    Returns:
        ``(u, info, vals)`` as :func:`jaxfem.newton.newton_solve`, host numpy.
    """
    k = kernels
    u0 = np.asarray(u0, np.float64)
    n = u0.shape[0]
    rows, cols, fixed, free = host["rows"], host["cols"], host["fixed"], host["free"]
    keep, diag_fixed = host["keep"], host["diag_fixed"]
    uD0, uD1 = np.asarray(loads0["u_D"], np.float64), np.asarray(theta["u_D"], np.float64)
    forces: dict = {}

    def f_ext(s):
        if s not in forces:
            forces[s] = np.asarray(k.external(theta, loads0, s, arrays))
        return forces[s]

    def u_D(s):
        return uD0 + s * (uD1 - uD0)

    def min_det(u):
        return float(k.min_det(theta, u, arrays)) if finite else 1.0

    def guarded(u, du):
        if not opts.line_search:
            return u + du, True
        a, j, d = 1.0, 0, min_det(u + du)
        while d <= 0 and j <= opts.line_search:
            a, j = 0.5 * a, j + 1
            d = min_det(u + a * du)
        return u + a * du, d > 0

    lam0 = np.full((host["n_cells"], k.n_qp), np.nan)
    st = {"u": u0, "lam": lam0, "vals": None, "u_eq": u0, "lam_eq": lam0, "s": 0.0, "s_new": 0.0,
          "ds": float(opts.initial_step), "mode": PREDICT, "it": 0, "bad": 0, "res0": np.inf, "dun": np.inf,
          "steps": 0, "accepted": 0, "cutbacks": 0, "iterations": 0, "reason": OK, "fail_s": 0.0,
          "fail_step": 0}
    log = np.full(opts.log_size, np.nan)
    log_step = np.full(opts.log_size, -1)
    iters_log = np.zeros(opts.max_steps, np.int32)
    n_log = 0

    def running(st):
        return st["s"] < 1.0 and st["ds"] >= opts.min_step and st["steps"] < opts.max_steps

    def end_attempt(st, accepted, reason):
        grow = 2.0 if st["it"] <= opts.grow_below else 1.0
        if accepted:
            new = {**st, "u_eq": st["u"], "lam_eq": st["lam"], "s": st["s_new"], "ds": min(st["ds"] * grow, 1.0),
                   "accepted": st["accepted"] + 1}
        else:
            new = {**st, "u": st["u_eq"], "lam": st["lam_eq"], "ds": 0.5 * st["ds"], "cutbacks": st["cutbacks"] + 1,
                   "reason": reason, "fail_s": st["s"], "fail_step": st["accepted"]}
        iters_log[min(st["steps"], opts.max_steps - 1)] = st["it"]
        return {**new, "mode": PREDICT, "steps": st["steps"] + 1, "iterations": st["iterations"] + st["it"] + 1}

    while running(st):
        R_int, vals, lam = k.evaluate(theta, st["u"], st["lam"], arrays)
        R_int, vals = np.asarray(R_int), np.asarray(vals)
        st = {**st, "lam": lam, "vals": vals}
        correcting = st["mode"] == CORRECT
        failed = False
        if correcting:  # a correction's outcome: converged, failed, or go on
            s = st["s_new"]
            R = R_int - f_ext(s)
            res = _norm(R * free)
            scale = max(max(_norm(R * (1 - free)), _norm(f_ext(s) * free)), 1e-300)
            unorm = max(_norm(st["u"]), 1e-300)
            miss = _norm(u_D(s) - st["u"][fixed])
            conv = (st["it"] > 0 and res <= opts.rtol * scale and st["dun"] <= opts.utol * unorm
                    and miss <= 1e-10 * max(_norm(u_D(s)), unorm))
            stalled = res > opts.progress * st["res0"] and res > 100 * opts.rtol * scale and st["it"] > 0
            bad = st["bad"] + 1 if stalled else 0
            hopeless = opts.diverge_after > 0 and bad >= opts.diverge_after
            nan = not np.isfinite(res)
            failed = not conv and (nan or hopeless or st["it"] >= opts.max_iter)
            if st["it"] > 0:
                i = min(n_log, opts.log_size - 1)
                log[i], log_step[i] = res / scale, st["steps"]
                n_log += 1
            st = {**st, "bad": bad, "res0": res}
            if conv or failed:
                st = end_attempt(st, conv, NAN if nan else NO_CONVERGENCE)
        if failed or not running(st):  # a failed attempt re-evaluates at the last equilibrium first
            continue
        predict = st["mode"] == PREDICT
        s_new = min(st["s"] + st["ds"], 1.0) if predict else st["s_new"]
        # one linear solve: the predictor from an equilibrium, or the next correction; the
        # prescribed values not yet met enter as a jump on the fixed dofs
        R = R_int - f_ext(s_new)
        gap = np.zeros(n)
        gap[fixed] = u_D(s_new) - st["u"][fixed]
        Kgap = np.bincount(rows, weights=vals * gap[cols], minlength=n)
        rhs = -(R + Kgap) * free + gap
        du = np.asarray(k.solve(vals * keep + diag_fixed, rhs), np.float64)
        bad_solve = not np.all(np.isfinite(du))
        u1, ok = guarded(st["u"], np.zeros(n) if bad_solve else du)
        nxt = {**st, "s_new": s_new, "dun": _norm(du), "mode": CORRECT}
        if predict:  # a predictor that would invert an element (or could not be solved) starts from the jump
            st = {**nxt, "u": u1 if ok and not bad_solve else st["u"] + gap, "it": 0, "bad": 0, "res0": np.inf,
                  "lam": np.full((host["n_cells"], k.n_qp), np.nan)}
        else:
            st = {**nxt, "u": u1, "it": st["it"] + 1}
            if bad_solve or not ok:
                st = end_attempt(st, False, SINGULAR if bad_solve else INVERTED)

    done = st["s"] >= 1.0
    status = OK if done else (NO_CONVERGENCE if st["reason"] == OK else st["reason"])
    info = {"status": np.int32(status), "load_factor": np.float64(st["s"]), "steps": np.int32(st["accepted"]),
            "attempts": np.int32(st["steps"]), "cutbacks": np.int32(st["cutbacks"]),
            "iterations": np.int32(st["iterations"]), "fail_step": np.int32(st["fail_step"]),
            "fail_load_factor": np.float64(st["fail_s"]), "residual_log": log, "log_step": log_step,
            "step_iterations": iters_log}
    u = st["u"] if done else np.full(n, np.nan)
    vals = st["vals"] if st["vals"] is not None else np.zeros(len(rows))
    return u, info, vals
