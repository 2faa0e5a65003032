"""A fit's evaluations solve the tangents only where the Jacobian is asked for
(refine.model.Compiled: Levenberg-Marquardt asks at its accepted steps; a rejected step and the
last one need the prediction alone), from the converged states Newton left (jaxfem.Solver.tangents_at):
the prediction alone solves no tangent, the Jacobian asked for afterwards solves one set per frame
and no Newton again, and both equal an evaluation that solved them together. A region model of a
small sheet, its motion, noise, place and evaluation point drawn under a seed."""

import numpy as np

from tests.test_shared_programs import Z, _region_models


def test_the_prediction_alone_solves_no_tangent_and_the_jacobian_reuses_its_states(monkeypatch):
    import jaxfem.solver as solver_module
    from refine.model.objective import Compiled

    rng = np.random.default_rng(41)
    (model, param), _ = _region_models(rng)
    calls = {"newton": 0, "tangents": 0}
    newton, tangents = solver_module.Solver.solve_for_adjoint, solver_module.Solver.tangents_at

    def counted(name, fn):
        def wrapper(*a, **kw):
            calls[name] += 1
            return fn(*a, **kw)
        return wrapper

    monkeypatch.setattr(solver_module.Solver, "solve_for_adjoint", counted("newton", newton))
    monkeypatch.setattr(solver_module.Solver, "tangents_at", counted("tangents", tangents))
    z = Z + rng.normal(0, 0.02, Z.size)
    lazy = Compiled(model, param)
    pred = lazy.predict(z)
    frames = model.obs.n_frames
    assert calls == {"newton": frames, "tangents": 0}
    J = lazy.jacobian(z)
    assert calls == {"newton": frames, "tangents": frames}
    assert lazy.predict(z) is pred and lazy.jacobian(z) is J and calls["newton"] == frames
    together_pred, together_J = Compiled(model, param).evaluate(z)  # Jacobian first, then the prediction
    np.testing.assert_array_equal(pred, together_pred)
    np.testing.assert_array_equal(J, together_J)
    lazy.predict(z + 0.01)  # another point: Newton again, still no tangent
    assert calls["tangents"] == 2 * frames and calls["newton"] == 3 * frames
