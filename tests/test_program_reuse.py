"""A smaller mesh reuses a larger padding its program was already given (jaxfem.program.Program.sizes_for):
no compile of its own bucket, the same solve as at its real sizes. Small sheets, their sizes and
loads drawn under a seed."""

import numpy as np

import jaxfem as jf
from jaxfem import padding
from jaxfem.assembly import make_pattern
from jaxfem.program import REUSE
from tests.test_shared_programs import COMPILES, unpadded_solve


def _sheet(nx, ny, rng, law="neo-hookean"):
    mesh = jf.rectangle(0, 0, 100, 60, nx, ny)
    fixed = np.concatenate([jf.dofs(mesh, mesh.side("left")), jf.dofs(mesh, mesh.side("right"))])
    problem = jf.Problem(mesh, law, "plane-stress", fixed=fixed)
    stretch, shear = rng.uniform(5, 15), rng.uniform(-3, 3)
    pull = problem.prescribe(lambda X: np.where(X[:, :1] > 50, [stretch, shear], 0.0))
    E = rng.uniform(50, 100, mesh.n_cells)
    return jf.Solver(problem, "superlu"), problem.params(E=E, nu=0.3, thickness=1.0, u_D=pull)


def test_a_coarser_mesh_after_a_finer_one_reuses_its_padding_and_solves_the_same():
    """A sheet, then one of about half its cells (sizes drawn): the second is padded to the
    first's sizes, its solve compiles nothing, and its displacements are those of its real sizes
    (the dense solver on the unpadded system); a mesh more than REUSE times smaller keeps a
    bucket of its own."""
    rng = np.random.default_rng(31)
    nx, ny = int(rng.integers(13, 17)), int(rng.integers(8, 11))
    # Saint Venant-Kirchhoff: a law no other test of this process pads for, so the first sheet's
    # bucket is the program's only one
    fine, theta_f = _sheet(nx, ny, rng, "saint-venant-kirchhoff")
    coarse, theta_c = _sheet(int(round(nx / 1.4)), int(round(ny / 1.4)), rng, "saint-venant-kirchhoff")
    assert coarse.program is fine.program
    own = padding.sizes(coarse.sizes.n_cells, coarse.sizes.n_nodes, 2, coarse.sizes.nnz, coarse.sizes.n_fixed)
    assert own.n_cells_p < fine.sizes.n_cells_p <= REUSE * coarse.sizes.n_cells
    assert (coarse.sizes.n_cells_p, coarse.sizes.n_nodes_p, coarse.sizes.nnz_p, coarse.sizes.n_fixed_p) == \
        (fine.sizes.n_cells_p, fine.sizes.n_nodes_p, fine.sizes.nnz_p, fine.sizes.n_fixed_p)
    fine.solve(theta_f)
    with COMPILES as c:
        u = coarse.solve(theta_c).u
    assert c.n == 0, f"the coarser mesh compiled {c.n} programs"
    want = unpadded_solve(coarse, theta_c)
    np.testing.assert_allclose(u, want, atol=1e-9 * np.abs(want).max())
    assert np.abs(np.asarray(u)).max() > 1.0
    tiny, _ = _sheet(3, 2, rng, "saint-venant-kirchhoff")
    assert tiny.sizes.n_cells_p < coarse.sizes.n_cells_p


def test_fits_says_which_paddings_hold_a_mesh():
    """padding.fits over random sizes: a problem fits its own bucket and every padding that
    fits builds valid arrays (sorted unique padding entries, real entries first)."""
    rng = np.random.default_rng(5)
    for _ in range(20):
        nx, ny = (int(v) for v in rng.integers(2, 9, 2))
        mesh = jf.rectangle(0, 0, 10, 6, nx, ny)
        pat = make_pattern(mesh)
        fixed = jf.dofs(mesh, mesh.side("left"))
        own = padding.sizes(mesh.n_cells, mesh.n_nodes, 2, pat.nnz, len(fixed))
        assert padding.fits(own, own)
        big = padding.sizes(4 * mesh.n_cells, 4 * mesh.n_nodes, 2, 4 * pat.nnz, 2 * len(fixed))
        assert padding.fits(own, big) and not padding.fits(big, own)
        s = padding.padded_to(own, big)
        free = np.ones(mesh.n_nodes * 2, bool)
        free[fixed] = False
        arr = padding.padded_arrays(s, mesh.cells, pat, np.sort(fixed), free)
        assert arr["rows"].shape == (s.nnz_p,) and arr["cells"].shape[0] == s.n_cells_p
        pairs = arr["rows"].astype(np.int64) * s.n_dofs_p + arr["cols"]
        assert len(np.unique(pairs)) == s.nnz_p  # every entry at a place of its own
        np.testing.assert_array_equal(arr["rows"][: pat.nnz], pat.rows)


def test_headroom_pads_for_a_larger_mesh_that_then_shares_it():
    """A solver built with headroom 1.25 is padded as for a mesh 1.25 times larger; a finer
    sheet within that room, built after it, is given the same padding (no bucket of its own);
    one beyond it keeps its own. Constructing solvers compiles nothing (cheap)."""
    rng = np.random.default_rng(11)
    nx, ny = int(rng.integers(10, 14)), int(rng.integers(6, 9))
    mesh = jf.rectangle(0, 0, 100, 60, nx, ny)
    fixed = np.concatenate([jf.dofs(mesh, mesh.side("left")), jf.dofs(mesh, mesh.side("right"))])
    # Mooney-Rivlin under plane strain: a program no other test of this process pads for
    search = jf.Solver(jf.Problem(mesh, "mooney-rivlin", "plane-strain", fixed=fixed), "superlu", headroom=1.25)
    s = search.sizes
    assert s.n_cells_p >= 1.25 * s.n_cells and s.n_nodes_p >= 1.25 * s.n_nodes and s.nnz_p >= 1.25 * s.nnz
    wider = jf.rectangle(0, 0, 100, 60, nx + 1, ny)  # about 1 / nx more cells
    fixed_w = np.concatenate([jf.dofs(wider, wider.side("left")), jf.dofs(wider, wider.side("right"))])
    hyp = jf.Solver(jf.Problem(wider, "mooney-rivlin", "plane-strain", fixed=fixed_w), "superlu")
    assert hyp.sizes.n_cells > s.n_cells and padding.fits(hyp.sizes, s)
    assert (hyp.sizes.n_cells_p, hyp.sizes.n_nodes_p, hyp.sizes.nnz_p, hyp.sizes.n_fixed_p) == \
        (s.n_cells_p, s.n_nodes_p, s.nnz_p, s.n_fixed_p)
    big = jf.rectangle(0, 0, 100, 60, 2 * nx, 2 * ny)
    fixed_b = np.concatenate([jf.dofs(big, big.side("left")), jf.dofs(big, big.side("right"))])
    other = jf.Solver(jf.Problem(big, "mooney-rivlin", "plane-strain", fixed=fixed_b), "superlu")
    assert other.sizes.n_cells_p > s.n_cells_p
