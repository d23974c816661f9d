"""Evaluation: the paper's measures, ATE with alignment, RPE as evo defines it."""

import math

import numpy as np
import pytest

import diffdrive as dd
from diffdrive.evaluation import align, ate, rpe, run_errors, worst


def straight(n=11, step=0.1):
    return np.column_stack([np.arange(n) * step, np.zeros(n), np.zeros(n)])


def test_run_errors_worked_case():
    truth = straight()
    estimate = truth.copy()
    estimate[5] += [0.0, 0.03, math.radians(2)]
    estimate[-1] += [0.01, 0.0, math.radians(-1)]
    errors = run_errors(estimate, truth)
    assert errors.max_position == pytest.approx(0.03)
    assert errors.max_heading == pytest.approx(2.0)
    assert errors.final_position == pytest.approx(0.01)
    assert errors.final_heading == pytest.approx(1.0)
    assert worst([errors, run_errors(truth, truth)]) == errors


def test_ate_is_zero_after_aligning_a_rigidly_moved_trajectory():
    t = np.linspace(0, 6, 200)
    truth = np.column_stack([np.cos(t), np.sin(2 * t), t])
    moved = dd.batch.compose(np.array([0.4, -1.2, 0.7]), truth)
    assert ate(moved, truth) > 0.5
    assert ate(moved, truth, aligned=True) == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(align(moved, truth), truth, atol=1e-12)


def test_ate_is_the_rmse_of_position_errors():
    truth = straight(5)
    estimate = truth + np.array([[0, 0.1, 0], [0, -0.1, 0], [0, 0.1, 0], [0, -0.1, 0], [0, 0.1, 0]])
    assert ate(estimate, truth) == pytest.approx(0.1)


def test_rpe_of_a_constant_heading_bias():
    """Odometry that turns 1 degree a step too far: each 1-step motion is off by 1 degree."""
    n = 20
    truth = straight(n + 1)
    estimate = np.zeros_like(truth)
    for k in range(n):  # the odometry's own steps of 0.1 m with a 1 degree extra turn
        estimate[k + 1] = dd.batch.compose(estimate[k], np.array([0.1, 0.0, math.radians(1)]))
    translation, rotation = rpe(estimate, truth, 1, unit="poses")
    assert rotation == pytest.approx(1.0)
    assert translation == pytest.approx(0.0, abs=1e-12)
    # Over 0.2 m (two steps) the motion's end is off by the first step's turn.
    translation, rotation = rpe(estimate, truth, 0.2, unit="m")
    assert rotation == pytest.approx(2.0)
    assert translation == pytest.approx(
        0.1 * math.sin(math.radians(1)) * math.hypot(1, 0), rel=1e-3
    )


def test_rpe_and_ate_refuse_bad_input():
    truth = straight()
    with pytest.raises(ValueError, match="must both have shape"):
        ate(truth[:5], truth)
    with pytest.raises(ValueError, match="needs the times"):
        rpe(truth, truth, 1.0, unit="s")
    with pytest.raises(ValueError, match=r"no pair of poses is 5\.0 m apart"):
        rpe(truth, truth, 5.0)
