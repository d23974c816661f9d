"""Slip episodes: the optimal partition against exhaustive search, and what it finds."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import diffdrive as dd
from diffdrive.estimation import EstimatorSettings, Gyro, WholeLog, episodes, estimate_trajectory
from diffdrive.estimation.episodes import (
    EDGE_COST,
    EPISODE_PENALTY,
    episode_ratio,
    partition,
    partition_python,
    slip_episodes,
)


def gain(scaled, directions, episodes, penalty, cost):
    return sum(
        episode_ratio(scaled[a:b], directions[a:b]) - penalty - cost * (b - a) for a, b in episodes
    )


def exhaustive(scaled, directions, penalty, cost, longest):
    """The best summed gain over every set of disjoint runs of at most ``longest``."""
    n = len(scaled)
    runs = [(a, b) for a in range(n) for b in range(a + 1, min(n, a + longest) + 1)]
    best = 0.0
    for count in range(1, n + 1):
        for chosen in itertools.combinations(runs, count):
            ends = sorted(chosen)
            if all(ends[i][1] <= ends[i + 1][0] for i in range(len(ends) - 1)):
                best = max(best, gain(scaled, directions, ends, penalty, cost))
    return best


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.floats(-6, 6), min_size=1, max_size=6),
    st.lists(st.floats(-2, 2), min_size=12, max_size=12),
    st.floats(0.5, 12),
    st.floats(0.0, 2.0),
    st.integers(1, 6),
)
def test_the_partition_is_the_best_of_all(values, weights, penalty, cost, longest):
    scaled = np.array(values)
    directions = np.array(weights[: 2 * len(values)]).reshape(-1, 2)
    found = partition(scaled, directions, penalty, cost, longest)
    assert all(0 < b - a <= longest for a, b in found)
    assert all(found[i][1] <= found[i + 1][0] for i in range(len(found) - 1))
    best = exhaustive(scaled, directions, penalty, cost, longest)
    assert gain(scaled, directions, found, penalty, cost) == pytest.approx(best, rel=1e-9, abs=1e-9)


@pytest.mark.skipif(episodes._partition is None, reason="the C core was not built")
@settings(max_examples=40, deadline=None)
@given(
    st.integers(1, 300),
    st.integers(0, 2**32 - 1),
    st.sampled_from([1, 7, 50]),
    st.booleans(),
)
def test_the_c_partition_is_its_numpy_twin(n, seed, longest, ties):
    """Any log: the C programme finds the NumPy one's episodes exactly, ties (repeated
    values, wheels that do not turn) included."""
    rng = np.random.default_rng(seed)
    scaled = rng.normal(size=n) * rng.choice([1.0, 4.0], size=n)
    directions = rng.normal(size=(n, 2))
    if ties:
        scaled = np.round(scaled)
        directions = np.round(directions)  # zeros among them: a wheel that does not turn
    for penalty, cost in ((EPISODE_PENALTY, EDGE_COST), (2.0, 0.0), (8.0, 0.5)):
        assert partition(scaled, directions, penalty, cost, longest) == partition_python(
            scaled, directions, penalty, cost, longest
        )


def test_one_interval_alone_is_flagged_when_its_square_passes_the_penalty():
    directions = np.array([[1.0, -1.0]])
    root = (EPISODE_PENALTY + EDGE_COST) ** 0.5
    assert not slip_episodes(np.array([root - 0.1]), directions).any()
    assert slip_episodes(np.array([-(root + 0.1)]), directions).all()


def test_a_weak_persistent_slip_is_found_whole_and_noise_is_not():
    rng = np.random.default_rng(5)
    n = 4000
    directions = np.tile([-1.0, 0.8], (n, 1))
    scaled = rng.standard_normal(n)
    assert not slip_episodes(scaled, directions).any()
    # 20 intervals whose left wheel turns 3 standard deviations too far: each interval alone
    # passes the streaming test (3.29 standard deviations) about half the time
    scaled[1000:1020] += -3.0
    flagged = slip_episodes(scaled, directions)
    assert flagged[1000:1020].all()
    assert np.count_nonzero(flagged) <= 22


def test_a_slip_test_that_does_not_exist_is_refused_by_name():
    t = np.arange(4) * 0.1
    with pytest.raises(TypeError, match=r"WholeLog\.slip_episodes must be a bool, got 'window'"):
        WholeLog(slip_episodes="window")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="settings must be an EstimatorSettings, got dict"):
        estimate_trajectory(
            dd.DiffDrive(0.05, 0.3),
            t,
            np.ones((3, 2)),
            gyro=Gyro(t, np.zeros(4)),
            settings={"slip_test": "window"},  # type: ignore[arg-type]
        )


@pytest.mark.parametrize("speed", [0.5, 1.0, 5.0])
def test_a_noise_free_log_flags_no_slip(speed):
    """Wheels and gyro that agree to rounding: the whole-log test flagged 50 of 250 intervals
    (and 521 of 1000 at 5 rad/s) where its steady fit took out more wheel noise than the log
    has, leaving a matrix that is not positive definite and a steady share of hundreds."""
    import diffdrive as dd
    from diffdrive.estimation import Gyro, gyro_odometry

    robot = dd.DiffDrive(wheel_radius=0.05, track_width=0.3)
    t = np.arange(1001) * 0.02
    wheels = speed * np.stack([1 + 0.5 * np.sin(0.7 * t[:-1]), 1 + 0.5 * np.cos(0.5 * t[:-1])], -1)
    path = dd.simulate(robot, wheels, times=t)
    gyro = Gyro.from_yaw(t, path.poses[:, 2])
    increments = np.diff(path.wheel_positions, axis=0)
    found = gyro_odometry(robot, t, increments, gyro, EstimatorSettings(bias=0.0))
    assert not found.slip.any()
