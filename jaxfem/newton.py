"""Newton-Raphson with adaptive load stepping, entirely inside ``jax.jit``.

Each load step moves the loads (prescribed displacements, point forces, tractions) from where the
last converged state left them towards the target. A step starts with a consistent predictor (the
prescribed increment pushed through the tangent, so boundary elements are not torn), then Newton
corrections with a back-tracking guard against inverted elements. A step that fails is cut in half
and retried; a step that converged quickly lets the next one grow. Convergence needs both the free
residual (relative to the reaction and load scale) and the last increment (relative to the
displacement) to be small. An attempt that is going nowhere is abandoned early: when
``diverge_after`` corrections in a row fail to reduce the free residual by ``progress`` (Newton near
a solution reduces it by orders of magnitude), the step is cut back at once instead of running to
``max_iter``; a failed attempt then costs a few linear solves, not twenty.

The whole solve is one ``while_loop`` whose every pass evaluates the residual, the tangent and
the material state once, at the current point, and makes at most one linear solve: a correction of
the running load step, or (where the point is an equilibrium: the start, a converged step, or the
last equilibrium after a cut-back) the next step's predictor from the tangent already evaluated
there. The validity of an update (no inverted element) is checked on the geometry alone (det F),
so the material, whose derivatives are most of the program, appears once, and the tangent of the
last pass (at the converged state) is returned for the implicit derivative, which then needs no
tangent of its own (it compiles faster than a loop that evaluates the material in several places,
and runs as fast).

The material's inner state (the out-of-plane stretch of plane stress, solved per quadrature point)
travels with the iterate: each evaluation starts it where the last one converged.

The outcome is data (``status``, the failing step, the residual log), because nothing can be raised
inside ``jit``; :class:`~jaxfem.solver.Solver` turns a failure into a :class:`SolverError`.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp

from .assembly import facet_forces, matvec

OK, NO_CONVERGENCE, INVERTED, SINGULAR, NAN = 0, 1, 2, 3, 4
REASONS = {OK: "ok", NO_CONVERGENCE: "no-convergence", INVERTED: "inverted-element",
           SINGULAR: "singular-tangent", NAN: "nan"}


@dataclass(frozen=True)
class NewtonOptions:
    """Settings of the nonlinear solve (hashable: a change recompiles, a parameter change does not).

    Attributes:
        rtol: free residual <= rtol x (norm of reactions and external loads).
        utol: last Newton increment <= utol x norm of the displacement.
        max_iter: corrections per load step before the step is cut back.
        initial_step: first load increment (1 = try the full load at once).
        min_step: smallest load increment before giving up.
        max_steps: attempted load steps in all (accepted and cut back).
        grow_below: a step that converged in at most this many corrections doubles the next one.
        line_search: halvings allowed when a Newton update would invert an element.
        diverge_after: consecutive corrections without progress that end a load step attempt
            (0: never end early, run to ``max_iter``).
        progress: a correction makes progress when it multiplies the free residual by at most
            this factor (or the residual is already within 100 x ``rtol``).
        log_size: residual norms kept for the solver log.
    """

    rtol: float = 1e-9
    utol: float = 1e-4
    max_iter: int = 20
    initial_step: float = 1.0
    min_step: float = 1.0 / 1024
    max_steps: int = 100
    grow_below: int = 5
    line_search: int = 8
    diverge_after: int = 2
    progress: float = 0.7
    log_size: int = 256


def loads_at(theta, loads0, s):
    """Loads a fraction ``s`` of the way from ``loads0`` to ``theta``'s loads."""
    return {k: loads0[k] + s * (theta[k] - loads0[k]) for k in loads0}


def external_force(theta, loads, arrays, facet_element, n_dofs):
    """The external force ``(n_dofs,)``: point forces ``loads["f"]`` and the dead load of the
    traction facets ``arrays["tfacets"]`` (``loads["traction"]``: one ``(dim,)`` vector for every
    facet or ``(n_facets, dim)``), times ``arrays["facet_mask"]`` where given (0 on the padding's
    facets, :mod:`jaxfem.padding`: they carry nothing whatever the traction)."""
    f = loads["f"]
    facets = arrays["tfacets"]
    if facets.shape[0]:
        t = jnp.broadcast_to(loads["traction"], (facets.shape[0], theta["X"].shape[1]))
        if "facet_mask" in arrays:
            t = t * arrays["facet_mask"][:, None]
        f = f + facet_forces(theta["X"], facets, t, facet_element, n_dofs)
    return f


def newton_solve(theta, u0, loads0, arrays, *, asm, lin, opts: NewtonOptions, facet_element, finite, nnz=None):
    """Solve R(u; theta) = f_ext(theta) from the equilibrium ``u0`` of the loads ``loads0``.

    Args:
        theta: parameter pytree (see :meth:`Problem.params`).
        u0: start displacements ``(n_dofs,)``, in equilibrium with ``loads0``.
        loads0: the loads (``u_D``, ``f``, ``traction``) that ``u0`` satisfies.
        arrays: device index arrays of the pattern and the constraints.
    Returns:
        ``(u, info, vals)``: displacements ``(n_dofs,)``, a dict of counters and the residual log,
        and the (unconstrained) tangent values at ``u`` on the pattern, evaluated by the pass that
        found it converged (the implicit derivative's matrix, at no extra cost).
    """
    dim = theta["X"].shape[1]
    n = u0.shape[0]
    nnz = arrays["rows"].shape[0] if nnz is None else nnz
    free, fixed = arrays["free"], arrays["fixed"]
    p = {k: theta[k] for k in theta if k not in ("X", "thickness", "u_D", "f", "traction")}
    X, t = theta["X"], theta["thickness"]

    # One loop, one evaluation of the material per pass: each pass evaluates the residual, the
    # tangent and the material state at the current point, then either continues the load step's
    # corrections from it, or (the point being an equilibrium: the start, a converged step, or the
    # last equilibrium after a step was cut back) predicts the next load step from it. Every pass
    # makes at most one linear solve. The material laws' derivatives are the bulk of the program,
    # so one evaluation site instead of four (predictor and correction tangents, the guarded
    # update's residual and its fallback) halves what XLA compiles.
    #
    # ``lam`` is the material's inner state at each quadrature point (the out-of-plane stretch
    # under plane stress): each evaluation starts it from the last one (NaN: no start, after the
    # predictor's jump) and returns where it converged.
    PREDICT, CORRECT = 0, 1

    def evaluate(u, lam):
        R, vals, lam = asm.residual_and_tangent(u.reshape(-1, dim), X, p, t, arrays, nnz, lam)
        return R, vals, lam

    def constrained(vals):
        return vals * arrays["keep"] + arrays["diag_fixed"]

    def min_det(u):
        return (asm.min_jacobian(u.reshape(-1, dim), X, arrays["cells"], arrays.get("cell_mask")) if finite
                else jnp.array(1.0))

    def norms(R, loads):
        f_ext = external_force(theta, loads, arrays, facet_element, n)
        scale = jnp.maximum(jnp.linalg.norm(R * (1 - free)), jnp.linalg.norm(f_ext * free))
        return jnp.linalg.norm(R * free), jnp.maximum(scale, 1e-300)

    def guarded(u, du):
        """The update, halved while it would invert an element: ``(new u, valid)``."""
        if not opts.line_search:
            return u + du, jnp.array(True)

        def cond(c):
            a, k, d = c
            return (d <= 0) & (k <= opts.line_search)

        def halve(c):
            a, k, _ = c
            return 0.5 * a, k + 1, min_det(u + 0.5 * a * du)

        a, _, d = jax.lax.while_loop(cond, halve, (jnp.array(1.0), 0, min_det(u + du)))
        return u + a * du, d > 0

    def log(st, value):
        i = jnp.minimum(st["n_log"], opts.log_size - 1)
        return {**st, "log": st["log"].at[i].set(value), "log_step": st["log_step"].at[i].set(st["steps"]),
                "n_log": st["n_log"] + 1}

    def select(c, a, b):
        return jax.tree.map(lambda x, y: jnp.where(c, x, y), a, b)

    def end_attempt(st, accepted, reason):
        """Book-keeping of a load step attempt that converged (``accepted``) or failed with ``reason``."""
        grow = jnp.where(st["it"] <= opts.grow_below, 2.0, 1.0)
        ok = {**st, "u_eq": st["u"], "lam_eq": st["lam"], "s": st["s_new"],
              "ds": jnp.minimum(st["ds"] * grow, 1.0), "accepted": st["accepted"] + 1}
        cut = {**st, "u": st["u_eq"], "lam": st["lam_eq"], "ds": 0.5 * st["ds"], "cutbacks": st["cutbacks"] + 1,
               "reason": reason, "fail_s": st["s"], "fail_step": st["accepted"]}
        new = select(accepted, ok, cut)
        return {**new, "mode": jnp.array(PREDICT), "steps": st["steps"] + 1, "iterations": st["iterations"] + st["it"] + 1,
                "iters_log": new["iters_log"].at[jnp.minimum(st["steps"], opts.max_steps - 1)].set(st["it"])}

    def running(st):
        return (st["s"] < 1.0) & (st["ds"] >= opts.min_step) & (st["steps"] < opts.max_steps)

    def body(st):
        R_int, vals, lam = evaluate(st["u"], st["lam"])
        st = {**st, "lam": lam, "vals": vals}
        correcting = st["mode"] == CORRECT
        # --- a correction's outcome: converged, failed, or go on
        loads = loads_at(theta, loads0, st["s_new"])
        R = R_int - external_force(theta, loads, arrays, facet_element, n)
        res, scale = norms(R, loads)
        unorm = jnp.maximum(jnp.linalg.norm(st["u"]), 1e-300)
        miss = jnp.linalg.norm(loads["u_D"] - st["u"][fixed])  # prescribed values must be met too
        conv = ((st["it"] > 0) & (res <= opts.rtol * scale) & (st["dun"] <= opts.utol * unorm)
                & (miss <= 1e-10 * jnp.maximum(jnp.linalg.norm(loads["u_D"]), unorm)))
        stalled = (res > opts.progress * st["res0"]) & (res > 100 * opts.rtol * scale) & (st["it"] > 0)
        bad = jnp.where(stalled, st["bad"] + 1, 0)
        hopeless = (opts.diverge_after > 0) & (bad >= opts.diverge_after)
        nan = ~jnp.isfinite(res)
        failed = ~conv & (nan | hopeless | (st["it"] >= opts.max_iter))
        logged = select(correcting & (st["it"] > 0), log(st, res / scale), st)
        logged = {**logged, "bad": bad, "res0": res}
        ended = end_attempt(logged, conv, jnp.where(nan, NAN, NO_CONVERGENCE))
        st = select(correcting & (conv | failed), ended, select(correcting, logged, st))
        # an attempt that failed re-evaluates at the last equilibrium before predicting from it
        fresh = correcting & failed
        predict = (st["mode"] == PREDICT) & ~fresh
        s_new = jnp.where(predict, jnp.minimum(st["s"] + st["ds"], 1.0), st["s_new"])
        solve = running(st) & ~fresh
        # --- one linear solve: the predictor from an equilibrium, or the next correction; the
        # prescribed values not yet met enter as a jump on the fixed dofs
        loads = loads_at(theta, loads0, s_new)
        R = R_int - external_force(theta, loads, arrays, facet_element, n)
        gap = jnp.zeros(n).at[fixed].set(loads["u_D"] - st["u"][fixed])
        rhs = -(R + matvec(vals, arrays["rows"], arrays["cols"], gap)) * free + gap
        du = jax.lax.cond(solve, lambda: lin(constrained(vals), rhs, arrays), lambda: jnp.zeros(n))
        bad_solve = ~jnp.all(jnp.isfinite(du))
        u1, ok = guarded(st["u"], jnp.where(bad_solve, 0.0, du))
        # a predictor that would invert an element (or could not be solved) starts from the jump
        u_pred = jnp.where(ok & ~bad_solve, u1, st["u"] + gap)
        nxt = {**st, "s_new": s_new, "dun": jnp.linalg.norm(du), "mode": jnp.array(CORRECT)}
        pred = {**nxt, "u": u_pred, "it": 0, "bad": 0, "res0": jnp.array(jnp.inf),
                "lam": jnp.full_like(lam, jnp.nan)}
        corr = {**nxt, "u": u1, "it": st["it"] + 1}
        broke = bad_solve | ~ok
        corr = select(broke, end_attempt(corr, jnp.array(False), jnp.where(bad_solve, SINGULAR, INVERTED)), corr)
        return select(solve, select(predict, pred, corr), st)

    n_qp = asm.el.weights.shape[0]
    lam0 = jnp.full((arrays["cells"].shape[0], n_qp), jnp.nan)
    st0 = {"u": u0, "lam": lam0, "vals": jnp.zeros(nnz, u0.dtype), "u_eq": u0, "lam_eq": lam0, "s": jnp.array(0.0), "s_new": jnp.array(0.0),
           "ds": jnp.array(opts.initial_step), "mode": jnp.array(PREDICT), "it": 0, "bad": 0,
           "res0": jnp.array(jnp.inf), "dun": jnp.array(jnp.inf), "steps": 0, "accepted": 0,
           "cutbacks": 0, "iterations": 0, "reason": jnp.array(OK), "fail_s": jnp.array(0.0), "fail_step": 0,
           "log": jnp.full(opts.log_size, jnp.nan), "log_step": jnp.full(opts.log_size, -1), "n_log": 0,
           "iters_log": jnp.zeros(opts.max_steps, jnp.int32)}
    st = jax.lax.while_loop(running, body, st0)
    done = st["s"] >= 1.0
    status = jnp.where(done, OK, jnp.where(st["reason"] == OK, NO_CONVERGENCE, st["reason"]))
    info = {"status": status, "load_factor": st["s"], "steps": st["accepted"], "attempts": st["steps"],
            "cutbacks": st["cutbacks"], "iterations": st["iterations"], "fail_step": st["fail_step"],
            "fail_load_factor": st["fail_s"], "residual_log": st["log"], "log_step": st["log_step"],
            "step_iterations": st["iters_log"]}
    u = jnp.where(done, st["u"], jnp.nan)
    return u, info, st["vals"]
