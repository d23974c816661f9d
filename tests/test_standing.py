"""The gyro's settings from a log's standing stretches: its noise and bias recovered on
synthetic logs of known noise, the fallbacks said by name, and given figures winning."""

from __future__ import annotations

import math

import numpy as np
import pytest

import diffdrive as dd
from diffdrive.estimation import EstimatorSettings, Gyro, WholeLog, Window, estimate_trajectory
from diffdrive.estimation.gyro import gyro_odometry
from diffdrive.estimation.standing import identify_standing
from diffdrive.sensor_noise import DEFAULT_GYRO, GyroNoise

ROBOT = dd.DiffDrive(wheel_radius=0.1, track_width=0.5)
ARW, BIAS = 1e-3, 0.02  # rad/s/sqrt(Hz), rad/s


def _log(standing: float, seed: int, rate: float = 200.0, wheels: float = 20.0):
    """Wheels at 20 Hz standing ``standing`` s then driving an arc; a gyro at ``rate`` Hz of
    white noise ``ARW`` about the true yaw rate plus ``BIAS``."""
    rng = np.random.default_rng(seed)
    times = np.arange(0.0, standing + 10.0 + 1e-9, 1.0 / wheels)
    moving = times[:-1] >= standing - 1e-9
    increments = np.where(moving[:, None], np.array([0.4, 0.5]), 0.0)  # rad a step
    yaw_rate = ROBOT.to_twist(dd.WheelVelocities(0.4 * wheels, 0.5 * wheels)).omega
    samples = np.arange(0.0, times[-1] + 1e-9, 1.0 / rate)
    true = np.where(samples >= standing, yaw_rate, 0.0)
    rates = true + BIAS + ARW * math.sqrt(rate) * rng.standard_normal(len(samples))
    return times, increments, Gyro(samples, rates)


@pytest.mark.parametrize("seed", range(5))
def test_a_long_stretch_gives_the_noise_by_its_allan_deviation(seed):
    """30 s standing, the gyro at 200 Hz: the angle random walk within 5 %, the bias within
    three of its standard errors, which is the prior handed on."""
    times, increments, gyro = _log(30.0, seed)
    turned = np.diff(gyro.angles(times))
    fit = identify_standing(times, increments, turned, samples=(gyro.times, gyro.rates))
    assert fit is not None
    assert fit.noise.angle_random_walk == pytest.approx(ARW, rel=0.05)
    standard_error = ARW / math.sqrt(30.0)
    assert fit.noise.initial_bias_sigma == pytest.approx(standard_error, rel=0.10)
    assert abs(fit.bias - BIAS) < 3 * standard_error
    assert fit.standing == pytest.approx(30.0)
    assert "the Allan deviation of the gyro's" in fit.report[1]
    assert fit.report[0].startswith(f"gyro bias {fit.bias:.3g} rad/s")


def test_a_short_stretch_gives_the_noise_by_the_spread_and_says_the_default_it_kept():
    times, increments, gyro = _log(0.4, 0, rate=20.0)  # 8 gyro samples standing: no Allan
    turned = np.diff(gyro.angles(times))
    assert identify_standing(times, increments, turned, samples=(gyro.times, gyro.rates)) is None
    times, increments, gyro = _log(2.0, 1, rate=20.0)  # 40 samples: the spread
    turned = np.diff(gyro.angles(times))
    fit = identify_standing(times, increments, turned, samples=(gyro.times, gyro.rates))
    assert fit.noise.angle_random_walk == pytest.approx(ARW, rel=0.35)
    assert fit.noise.rate_random_walk == DEFAULT_GYRO.rate_random_walk
    assert "too few or uneven for an Allan deviation" in fit.report[1]
    assert "the default" in fit.report[2]


def test_the_whole_log_takes_the_identified_settings_unless_given():
    times, increments, gyro = _log(20.0, 2)
    found = estimate_trajectory(ROBOT, times, increments, gyro=gyro, smooth=False)
    turned = np.diff(gyro.angles(times))
    fit = identify_standing(times, increments, turned, samples=(gyro.times, gyro.rates))
    head = len(fit.report)  # then the wheels' noise, against the gyro
    assert found.settings[:head] == fit.report
    assert "from their turn against the gyro's" in found.settings[head]
    settings = EstimatorSettings(gyro_noise=fit.noise, bias=fit.bias)
    explicit = estimate_trajectory(
        ROBOT, times, increments, gyro=gyro, smooth=False, settings=settings
    )
    np.testing.assert_array_equal(found.poses, explicit.poses)
    assert explicit.settings[0] == "gyro noise and bias: as given"
    mine = GyroNoise(angle_random_walk=5e-3, rate_random_walk=1e-4, initial_bias_sigma=1e-2)
    given = estimate_trajectory(
        ROBOT,
        times,
        increments,
        gyro=gyro,
        smooth=False,
        settings=EstimatorSettings(gyro_noise=mine),
    )
    assert given.settings[1] == "gyro noise: as given"
    assert given.settings[0].startswith("gyro bias")  # the bias still from the stretch
    assert given.states[0, 3] == pytest.approx(fit.bias)


def test_a_log_that_never_stands_still_says_which_defaults_it_used():
    times, increments, gyro = _log(0.0, 3)
    estimate = estimate_trajectory(ROBOT, times, increments, gyro=gyro, smooth=False)
    line, *wheels_lines = estimate.settings
    assert wheels_lines[-1].startswith("wheel noise: k ")
    assert line.startswith("no standing stretch of 0.5 s in the log")
    assert f"the gyro noise is the default ({DEFAULT_GYRO})" in line
    assert "the bias starts at 0 rad/s" in line
    with pytest.raises(ValueError, match="heading 'gyro' needs the gyro bias"):
        gyro_odometry(ROBOT, times, increments, gyro, EstimatorSettings("gyro"))
    wheels = EstimatorSettings("wheels")
    (default,) = estimate_trajectory(ROBOT, times, increments, settings=wheels).settings
    assert default == (
        "wheel noise: k = 0.0001 m on both wheels, the default (no gyro to tell it; "
        "EstimatorSettings.wheel_noise to give it)"
    )


def test_the_command_line_prints_what_it_used(tmp_path, capsys):
    from diffdrive.cli import main

    times, increments, gyro = _log(20.0, 4)
    rates = np.interp(times, gyro.times, gyro.rates)
    ticks = np.vstack([[0, 0], np.cumsum(increments, axis=0)]) * 4096 / (2 * math.pi)
    rows = ["t,left_ticks,right_ticks,gyro_z"]
    rows += [
        f"{t:.4f},{round(a)},{round(b)},{g:.6f}"
        for t, (a, b), g in zip(times, ticks, rates, strict=True)
    ]
    (tmp_path / "log.csv").write_text("\n".join(rows) + "\n")
    (tmp_path / "robot.toml").write_text(
        "left_wheel_radius = 0.1\nright_wheel_radius = 0.1\ntrack_width = 0.5\n"
        "ticks_per_revolution = 4096\n"
    )
    argv = ["odometry", str(tmp_path / "log.csv"), "--robot", str(tmp_path / "robot.toml")]
    assert main([*argv, "-o", str(tmp_path / "out.csv")]) == 0
    printed = capsys.readouterr().out
    assert "angle random walk" in printed
    assert "bias prior" in printed


def test_a_streaming_estimator_starts_from_a_warm_up(monkeypatch):
    """The first 20 s (the robot standing) identify the gyro; the streaming estimator then
    fed the whole log is the whole-log filter given the same settings (the wheels' noise
    given, and without what a stream given angles cannot know: how far the gyro's samples
    leave each turn open)."""
    from diffdrive.estimation import Gyro, PoseEstimator, warm_up

    monkeypatch.setattr(Gyro, "interpolation_variances", lambda self, at: np.zeros(len(at) - 1))
    times, increments, gyro = _log(20.0, 5)
    head = times <= 20.0
    fit = warm_up(times[head], increments[: np.count_nonzero(head) - 1], gyro)
    assert fit.noise.angle_random_walk == pytest.approx(ARW, rel=0.05)
    settings = fit.settings(EstimatorSettings(wheel_noise=1e-4))
    assert (settings.gyro_noise, settings.bias) == (fit.noise, fit.bias)
    whole = estimate_trajectory(
        ROBOT,
        times,
        increments,
        gyro=gyro,
        smooth=False,
        settings=settings.replace(whole_log=WholeLog(slip_episodes=False)),
    )
    streaming = PoseEstimator(
        ROBOT,
        settings.replace(window=Window(np.inf, 0.0)),
        initial_time=float(times[0]),
    )
    turned = np.diff(gyro.angles(times))
    for k in range(1, len(times)):
        streaming.update_increments(*increments[k - 1], times[k], gyro_angle=turned[k - 1])
    np.testing.assert_allclose(streaming.state, whole.states[-1], rtol=1e-9, atol=1e-11)
