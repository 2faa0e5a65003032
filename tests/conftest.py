"""Shared test set-up: compile for speed, free compiled programs between test modules, and the
checks moved out of the default suite.

Most of the suite's seconds are XLA compiling small programs (one small diagnosis compiles ~200),
not running them: the tests compile without LLVM's expensive optimisations
(``--xla_backend_optimization_level=0 --xla_llvm_disable_expensive_passes=true``, added to any
``XLA_FLAGS`` already set; ``NONRIGID_TEST_XLA_OPT=1`` keeps XLA's defaults). Measured on the
2-core machine: a 117-point diagnosis' compiles 162 -> 96 s and its CPU 132 -> 110 s;
tests/test_derivatives.py + test_verify_patch.py 232 -> 178 CPU s, test_fit.py + test_real_outlines.py
154 -> 125 CPU s, the same results (the flags change how fast code is generated, not what it computes).

Every model compiles its own solve (one XLA executable per mesh and parametrisation); a pytest
worker that runs many modules otherwise keeps them all. (The worker that once grew past 11 GB
was mostly SciPy's SuperLU leaking factorisations freed on another thread, fixed in
jaxfem.linsolve; the executables are still worth freeing once a module is done with them.)
"""

import gc
import os

FAST_COMPILE = "--xla_backend_optimization_level=0 --xla_llvm_disable_expensive_passes=true"
if os.environ.get("NONRIGID_TEST_XLA_OPT") != "1" and FAST_COMPILE not in os.environ.get("XLA_FLAGS", ""):
    # before the first computation initialises the backend (it reads XLA_FLAGS then); workers a
    # test starts (refine.batch) inherit it
    os.environ["XLA_FLAGS"] = f"{os.environ.get('XLA_FLAGS', '')} {FAST_COMPILE}".strip()

import jax  # noqa: E402
import pytest  # noqa: E402


@pytest.fixture(autouse=True, scope="module")
def _free_compiled_programs():
    yield
    jax.clear_caches()
    gc.collect()


# Checks moved out of the default suite to keep it under 15 minutes on 2 cores (they still run
# with `-m slow`, as the benchmarks' slower checks do). Session 23 measured the default suite at
# 1273-1279 s on a 2-core AMD EPYC machine (fresh-clone .ci/run, three runs): over budget. These
# are its longest single checks (pytest --durations at load ~10, each 100-800 s there, ~25-190 s
# quiet), each covered in the default suite by a lighter sibling named beside it, or by a benchmark.
SLOW_IN_CI = {
    # an end-to-end hidden-hole diagnosis: tests/test_outputs.py diagnoses a hidden region end to end;
    # benchmarks/diagnose.py's hole cells and tests/test_real_outlines.py the holes
    "tests/test_diagnose.py::test_finds_the_hidden_effect[hole-12]",
    # the notebooks' code paths are the tests of test_paper.py, test_tracking*.py, test_diagnose.py
    "tests/test_notebooks.py::test_notebook_executes[paper_section3.ipynb]",
    "tests/test_notebooks.py::test_notebook_executes[tracking.ipynb]",
    "tests/test_notebooks.py::test_notebook_executes[diagnose.ipynb]",
    # Taylor tests: the other parametrisations (plane strain, tet4; the fibre angle) stay
    "tests/test_derivatives.py::test_taylor_rate_is_two[plane-stress-E-reverse]",
    "tests/test_fibre_law.py::test_taylor_rate_is_two_for_the_fibre_angle_and_stiffness[fibre_stiffness-1.0-reverse]",
    # series: the plane-strain quad4 path stays; the nested derivatives' order 3 was already slow
    "tests/test_series.py::test_series_matches_forward_solves_along_the_path[plane-stress-tri6-E]",
    "tests/test_series.py::test_series_agrees_with_nested_implicit_derivatives[2]",
    # the hand is a slow area (the guide: 3D, hand, real sequences); its fast tests stay
    "tests/test_hand_tracking.py::test_restart_from_other_starts_when_the_fit_ends_high",
    "tests/test_hand_tracking.py::test_tracker_jacobian_passes_a_taylor_test",
    # optimisers and refits: the least-squares and Brent paths of test_paper.py and test_fit.py stay
    "tests/test_paper.py::test_lbfgsb_agrees_with_least_squares",
    "tests/test_fit.py::test_tv_field_by_lbfgsb_shows_the_stiff_region",
    "tests/test_fit.py::test_forces_make_the_background_absolute",
    "tests/test_refined_model.py::test_the_refined_bundle_reproduces_the_chosen_model[ellipse-1]",
    # SuperLU's thread-affine freeing: tests/test_linsolve_*.py's other checks stay
    "tests/test_linsolve_superlu.py::test_factorisations_are_made_and_freed_on_one_thread",
    # Session 24 (the suite still 1184 s in a quiet fresh clone at 0802e4c; durations from that run):
    # batch: its planning, paths, worker settings and resumable rows stay in tests/test_batch.py;
    # benchmarks/batch.py runs whole batches
    "tests/test_batch.py::test_batch_matches_one_by_one_records_the_broken_bundle_and_resumes",
    # the hand (a slow area): the tracker's Taylor-free checks and the hand tests stay
    "tests/test_hand_tracking.py::test_each_frame_starts_from_the_constant_velocity_prediction",
    # Taylor: plane strain and tet4 reverse stay (forward mode is the same implicit derivative)
    "tests/test_derivatives.py::test_taylor_rate_is_two[plane-stress-E-forward]",
    # 3D correspondence fit (3D is a slow area): the 2D fit and Taylor test of test_correspond.py stay
    "tests/test_correspond_3d.py::test_fit_recovers_the_6dof_grip_and_the_dense_motion",
    # the plane-strain case of the same check stays
    "tests/test_assembly_kernels.py::test_material_state_start_does_not_change_the_result[plane-stress]",
    # refined bundles: tests/test_outputs.py's diagnosis writes and reads one; the others here stay
    "tests/test_refined_model.py::test_the_refined_bundle_reproduces_the_chosen_model[hole-3]",
    # known holes: the model mesh leaving them empty and their round trip stay in test_domain_holes.py
    "tests/test_domain_holes.py::test_a_known_hole_in_the_model_predicts_a_holed_sheet_better",
    # noise_std = 0: test_noise_std_zero_is_a_standard_deviation and the noise-free hidden region stay
    "tests/test_real_outlines.py::test_noise_free_data_meet_a_null_level_of_discretisation_error_alone",
}


@pytest.hookimpl(tryfirst=True)  # before `-m 'not slow'` deselects
def pytest_collection_modifyitems(config, items):
    for item in items:
        if item.nodeid in SLOW_IN_CI:
            item.add_marker(pytest.mark.slow)
