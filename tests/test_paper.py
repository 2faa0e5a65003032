"""The paper's Section 3.1 experiment: Brent from both middle points, the cubic fit, and gradients.

One synthetic experiment (the paper's moduli, noise 0.02 mm, data on a finer quadratic mesh of a
larger sheet) is shared by every test: building it and compiling its solves is most of the cost.
"""

from __future__ import annotations

import io

import numpy as np
import pytest

from refine.exceptions import IdentifiabilityError
from refine.diagnosis.forces import ForcedObjective
from examples.paper.experiment import (BRACKET, INCLUSION, MIDDLE_POINTS, NAME, EmbeddedRectangle, PaperExperiment, evaluations_to_reach, format_rows, solves_to_reach)


@pytest.fixture(scope="module")
def experiment():
    return PaperExperiment(EmbeddedRectangle())


@pytest.fixture(scope="module")
def brent_runs(experiment):
    return {b: experiment.brent(b) for b in MIDDLE_POINTS}


@pytest.fixture(scope="module")
def eq1_minimum(experiment):
    """The minimiser of eq. (1) itself (Brent to a tight tolerance): what Brent converges to."""
    return experiment.brent(MIDDLE_POINTS[1], tol=1e-7).values[NAME]


@pytest.mark.parametrize("middle", MIDDLE_POINTS)
def test_brent_from_both_middle_points_finds_the_inclusion(brent_runs, middle):
    r = brent_runs[middle]
    assert r.converged, r.message
    assert r.values[NAME] == pytest.approx(INCLUSION, rel=0.02)
    steps = [row["step"] for row in r.history]
    assert steps[0] == "initial" and steps[1] == "golden"  # as in Table 3: golden first ...
    assert steps.count("parabolic") > steps.count("golden")  # ... then mostly parabolic
    assert r.n_forward == len(r.history) <= 15
    assert all(BRACKET[0] <= row[NAME] <= BRACKET[1] for row in r.history)
    out = io.StringIO()
    r.table(file=out)
    assert "parabolic" in out.getvalue() and NAME in out.getvalue().splitlines()[0]


def test_tolerance_table_like_tables_1_and_2(experiment):
    rows = experiment.tolerance_table(MIDDLE_POINTS[0], tolerances=(0.1, 0.01))
    assert [row["tolerance"] for row in rows] == [0.1, 0.01]
    assert rows[0]["steps"] <= rows[1]["steps"]  # a finer tolerance costs steps
    assert abs(rows[1]["off_truth_percent"]) < 2.0
    assert "off_truth_percent" in format_rows(rows)


def test_cubic_fit_then_brent(experiment, eq1_minimum):
    r = experiment.cubic()
    assert r.converged, r.message
    assert [row["step"] for row in r.history[:4]] == ["fit"] * 4
    assert r.history[4]["step"] == "initial"  # the cubic's minimum starts the narrow search
    assert r.history[4][NAME] == pytest.approx(INCLUSION, rel=0.05)
    assert r.values[NAME] == pytest.approx(eq1_minimum, rel=2e-3)  # tolerance 0.001


def test_gradient_fit_reaches_its_minimum_in_fewer_solves_than_brent(experiment, brent_runs, eq1_minimum):
    lm = experiment.least_squares("lm")
    assert lm.converged, lm.message
    assert lm.values[NAME] == pytest.approx(INCLUSION, rel=0.02)
    n_lm = solves_to_reach(lm, lm.values[NAME], rel=1e-3)
    # Brent at the paper's tolerance may stop before 0.1 % of the eq. (1) minimum: count its
    # solves to 0.1 % from a run to a tight tolerance, starting at the same middle points
    n_brent = [solves_to_reach(experiment.brent(b, tol=1e-6), eq1_minimum, rel=1e-3) for b in MIDDLE_POINTS]
    assert n_lm is not None and None not in n_brent
    assert n_lm <= 5 and lm.n_forward <= 8
    # The target is a third of Brent's solves: Levenberg-Marquardt does not reach it (a
    # Newton step's linear model needs 4-5 solves from the uniform model); Pade steps do (below).
    assert n_lm < 0.7 * min(n_brent)


@pytest.mark.slow  # ~70 s (compiling the order-16 series); the notebook runs the same fit in CI
def test_one_pade_step_lands_within_a_tenth_of_a_percent(experiment):
    """The issue's target, a third of Brent's solves (7-8 here): from the uniform model (ratio 1;
    the minimiser is a factor ~10 away, beyond the radius of the equilibrium's Taylor series) the
    first Pade step lands within 0.1 % of the least-squares minimiser: 2 forward solves, the start
    and the step. (From Brent's middle points too: benchmarks/brent_vs_gradient.py, 5 seeds.)"""
    lm = experiment.least_squares("lm", rtol=1e-10, atol=1e-10)
    r = experiment.least_squares("pade")
    assert r.converged, r.message
    assert r.values[NAME] == pytest.approx(lm.values[NAME], rel=1e-5)
    assert solves_to_reach(r, lm.values[NAME], rel=1e-3) == 2
    assert r.n_forward == len(r.history) <= 4 and r.n_gradient <= r.n_forward


def test_lbfgsb_agrees_with_least_squares(experiment):
    r = experiment.lbfgsb()
    lm = experiment.least_squares("lm")  # compiled already by the test above
    assert r.values[NAME] == pytest.approx(lm.values[NAME], rel=1e-3)
    assert all("gradient_norm" in row and NAME in row for row in r.history)


def test_without_forces_the_modulus_is_relative(experiment):
    assert experiment.bundle.observations.forces is None
    with pytest.raises(IdentifiabilityError, match="relative elasticity"):
        ForcedObjective(experiment.model, experiment.param)


def test_evaluations_to_reach():
    errors = [5.0, 3.0, 4.0, 1.0, 2.0]
    estimates = [[10.0], [12.0], [9.0], [10.005], [10.0]]
    assert evaluations_to_reach(errors, estimates, [10.0], rel=1e-3) == 4
    assert evaluations_to_reach(errors, estimates, [12.0], rel=1e-3) is None
    assert evaluations_to_reach(errors[:2], estimates[:2], [12.0], rel=1e-3) == 2


@pytest.mark.slow
def test_noise_free_brent_is_within_half_a_percent():
    ex = PaperExperiment(EmbeddedRectangle(noise=0.0))
    for b in MIDDLE_POINTS:
        assert ex.brent(b, tol=1e-4).values[NAME] == pytest.approx(INCLUSION, rel=5e-3)
    assert np.isfinite(ex.error_curve([100.0, 800.0])).all()
