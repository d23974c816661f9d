"""MPPI: the update on a problem whose optimum is known, tracking through a delay within the
wheels' limit, a batch of robots, and bad settings refused by name."""

from __future__ import annotations

import math

import numpy as np
import pytest

import diffdrive as dd
from diffdrive.control import MPPI, MPPICosts, PathLimits, follow, plan
from diffdrive.control.mppi import weighted_update

ROBOT = dd.DiffDrive(wheel_radius=0.1, track_width=0.6)


def test_the_update_is_the_weighted_mean_a_gaussian_works_out_to():
    """Perturbations e ~ N(0, s^2), costs (e - c)^2: weights exp(-(e - c)^2 / T) times the
    sampling density make a Gaussian whose mean is c s^2 / (s^2 + T / 2)."""
    rng = np.random.default_rng(0)
    sigma, temperature, target = 1.0, 1.0, 0.6
    noise = rng.normal(0.0, sigma, (400_000, 1))
    step, weights = weighted_update((noise[:, 0] - target) ** 2, noise, temperature)
    assert step[0] == pytest.approx(target * sigma**2 / (sigma**2 + temperature / 2), abs=5e-3)
    assert weights.sum() == pytest.approx(1.0)
    # A cost that does not depend on the sample: the plain mean of the perturbations.
    flat, _ = weighted_update(np.full(1000, 3.0), noise[:1000], temperature)
    assert flat[0] == pytest.approx(noise[:1000, 0].mean())


@pytest.mark.slow
@pytest.mark.parametrize("delay", [0.0, 0.1])
def test_it_follows_a_plan_through_a_known_delay_within_the_wheels_limit(delay) -> None:
    """Planned at 10 rad/s a wheel, the wheels' limit 12 the controller keeps (room to catch
    up); the commands in flight are rolled out first, so the delay costs little."""
    limits = PathLimits(max_velocity=1.0, max_acceleration=1.0, max_wheel_velocity=10.0)
    path = plan([(0, 0, 0), (3, 1, 0.5), (5, 3, 1.5)], ROBOT, limits)
    tracker = MPPI(delay=delay, max_wheel_velocity=12.0, seed=1)
    result = follow(path, tracker, dt=0.05, delay=delay)
    cross = np.abs(result.errors().cross_track)
    assert cross.mean() < 0.015
    assert cross.max() < 0.04
    assert np.abs(result.wheel_velocities).max() <= 12.0 * 1.005


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: MPPICosts(position=-1.0), "cost weight position must be >= 0"),
        (lambda: MPPICosts(rate=math.nan), "cost weight rate must be finite"),
        (lambda: MPPI(samples=0), "samples must be"),
        (lambda: MPPI(delay=0.07, dt=0.05), "delay must be a whole number of dt"),
        (lambda: MPPI(sigma=(0.1, 0.0)), "sigma must be"),
        (lambda: MPPI(samples=10**6, horizon=10**4), "MPPI's samples x horizon"),
    ],
)
def test_bad_settings_are_refused_by_name(make, message):
    with pytest.raises(ValueError, match=message):
        make()


def test_a_batch_of_robots_each_gets_its_own_sequence_and_the_count_is_kept() -> None:
    path = plan([(0, 0, 0), (2, 0, 0)], ROBOT, PathLimits(max_velocity=1, max_acceleration=1))
    tracker = MPPI(samples=64, horizon=10, seed=0)
    first = tracker.command(path, 0.0, np.array([[0.0, 0.0, 0.0], [0.0, 0.3, 0.0]]))
    assert first.shape == (2, 2)
    assert first[1, 1] < first[0, 1]  # the robot left of the path turns right, back to it
    with pytest.raises(ValueError, match="expected 2 poses as before, got 1"):
        tracker.command(path, 0.05, np.zeros((1, 3)))
    tracker.reset()
    assert tracker.command(path, 0.0, np.zeros((1, 3))).shape == (1, 2)
