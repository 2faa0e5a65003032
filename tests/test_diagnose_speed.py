"""What lets a diagnosis's stages run side by side (issue 22 item 2): a lock per compiled
executable (jaxfem.program.Program.lock_for), so a solver of another bucket size compiles and
solves while one is busy, and the chosen model's two discretisation fits in the diagnosis's
threads with the same figures as one after the other. Small sheets, loads drawn under a seed."""

import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

import jaxfem as jf


def _sheet(nx, ny, rng):
    mesh = jf.rectangle(0, 0, 100, 60, nx, ny)
    fixed = np.concatenate([jf.dofs(mesh, mesh.side("left")), jf.dofs(mesh, mesh.side("right"))])
    problem = jf.Problem(mesh, "neo-hookean", "plane-stress", fixed=fixed)
    stretch, shear = rng.uniform(5, 15), rng.uniform(-3, 3)
    pull = problem.prescribe(lambda X: np.where(X[:, :1] > 50, [stretch, shear], 0.0))
    E = rng.uniform(50, 100, mesh.n_cells)
    # SuperLU: a host solve, a Python callback that needs the GIL while the caller waits
    return jf.Solver(problem, "superlu"), problem.params(E=E, nu=0.3, thickness=1.0, u_D=pull)


def test_a_solver_of_another_bucket_solves_while_one_holds_its_lock():
    rng = np.random.default_rng(23)
    (a, _), (b, _) = _sheet(10, 6, rng), _sheet(9, 7, rng)
    big, theta = _sheet(24, 14, rng)
    assert a.program is b.program is big.program  # one program of the kind
    assert a.sizes != b.sizes and a.lock is b.lock  # one bucket: one executable, one lock
    assert big.sizes.n_cells_p != a.sizes.n_cells_p and big.lock is not a.lock
    out = {}
    with a.lock:  # a busy (or compiling) solver of the small bucket
        worker = threading.Thread(target=lambda: out.setdefault("u", np.asarray(big.displacement(theta))))
        worker.start()
        worker.join(timeout=300)
        done = not worker.is_alive()
    worker.join()
    assert done, "the other bucket's solve waited for the busy solver's lock"
    np.testing.assert_allclose(out["u"], np.asarray(big.displacement(theta)), rtol=1e-10, atol=1e-12)


@pytest.mark.slow
def test_the_discretisation_fits_side_by_side_give_the_figures_of_one_after_the_other():
    """A stiffer ellipse of random place, size and ratio in a sheet, data from the finer quadratic
    solve with noise; the chosen model's mesh and drive estimates (with_discretisation) fitted in
    a pool equal those fitted one after the other (to the solver's tolerance)."""
    from refine.diagnosis.fitted import fit, refit
    from refine.diagnosis.regions import regions_hypothesis
    from refine.diagnosis.shapes import RegionShape
    from refine.diagnosis.uncertainty import with_discretisation
    from refine.model.measured import MeasuredModel
    from refine.synthetic.sheet import Inclusion, Truth, synthetic_bundle

    rng = np.random.default_rng(57)
    cx, cy, angle = rng.uniform(17, 23), rng.uniform(13, 17), rng.uniform(0, 3)
    a, b, ratio = rng.uniform(3.5, 4.5), rng.uniform(2.5, 3.5), float(rng.uniform(3, 6))
    truth = Truth(inclusions=(Inclusion(jf.Ellipse(cx, cy, a, b, angle), ratio),))
    bundle = synthetic_bundle(truth, seed=57, roi=(5.0, 5.0, 35.0, 25.0), sheet=(0.0, 0.0, 40.0, 30.0), spacing=2.5,
                              noise=0.005, fractions=(1.0,), h=1.0)
    obs = bundle.observations
    guide, hold = obs.mask("guide"), obs.mask("validate")
    model = MeasuredModel(bundle.experiment, obs)
    sigma = 0.005
    start = RegionShape((cx, cy), (a, b), angle, "ellipse", ratio)
    f = refit(fit(regions_hypothesis(model, [start], [1]), guide, hold, sigma), guide, hold, sigma, element="tri6")
    one_by_one = with_discretisation(f, guide, hold, sigma)
    with ThreadPoolExecutor(2) as pool:
        side_by_side = with_discretisation(f, guide, hold, sigma, pool=pool)
    assert set(side_by_side.q_disc_parts) == set(one_by_one.q_disc_parts) == {"mesh", "drive"}
    for part in ("mesh", "drive"):
        np.testing.assert_allclose(side_by_side.q_disc_parts[part], one_by_one.q_disc_parts[part],
                                   rtol=1e-6, atol=1e-9, equal_nan=True)
    np.testing.assert_allclose(side_by_side.q_disc, one_by_one.q_disc, rtol=1e-6, atol=1e-9, equal_nan=True)
