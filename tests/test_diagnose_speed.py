"""The diagnosis's stages side by side (issue 22 item 2): the chosen model's two discretisation
fits in the diagnosis's threads give the figures of one after the other; and solvers of one
program, whatever their bucket size, take one lock (a lock per bucket let two executables with
PARDISO callbacks run at once, and a diagnosis hung: XLA's two pool threads each waited inside
``CpuPjRtRawLoadedExecutable::Execute`` while the callbacks, on its intra-op threads, waited for
buffers those executions were to make). Small sheets, loads drawn under a seed."""

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
    return jf.Solver(problem, "superlu"), problem.params(E=E, nu=0.3, thickness=1.0, u_D=pull)


def test_solvers_of_one_program_take_one_lock_whatever_their_bucket():
    """A sheet and a finer one (another bucket size) share the program and its one lock; no
    executable is built by constructing them (cheap)."""
    rng = np.random.default_rng(23)
    (small, _), (big, _) = _sheet(10, 6, rng), _sheet(int(rng.integers(22, 28)), int(rng.integers(12, 16)), rng)
    assert big.sizes.n_cells_p != small.sizes.n_cells_p
    assert small.program is big.program and small.program.lock is big.program.lock


@pytest.mark.slow
def test_the_discretisation_fits_side_by_side_give_the_figures_of_one_after_the_other():
    """A stiffer ellipse of random place, size and ratio in a sheet, data from the finer quadratic
    solve with noise; the chosen model's mesh and drive estimates (with_discretisation) fitted in
    a pool equal those fitted one after the other (to the solver's tolerance)."""
    from tests._ellipse_fit import fitted_ellipse

    from refine.diagnosis.uncertainty import with_discretisation

    sigma = 0.005
    f, guide, hold, _ = fitted_ellipse(57, noise=0.005, sigma=sigma)
    one_by_one = with_discretisation(f, guide, hold, sigma)
    with ThreadPoolExecutor(2) as pool:
        side_by_side = with_discretisation(f, guide, hold, sigma, pool=pool)
    assert set(side_by_side.q_disc_parts) == set(one_by_one.q_disc_parts) == {"mesh", "drive"}
    for part in ("mesh", "drive"):
        np.testing.assert_allclose(side_by_side.q_disc_parts[part], one_by_one.q_disc_parts[part],
                                   rtol=1e-6, atol=1e-9, equal_nan=True)
    np.testing.assert_allclose(side_by_side.q_disc, one_by_one.q_disc, rtol=1e-6, atol=1e-9, equal_nan=True)


