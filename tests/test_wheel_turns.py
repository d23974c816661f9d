"""The wheels' noise a whole log identifies from their turn against the gyro's
(``estimation.wheel_turns``), the counters' rounding as its floor, and how far a gyro's samples
leave its turn between them open (``Gyro.interpolation_variances``): the fused heading on a
clean log no worse than the wheels'."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import diffdrive as dd
from diffdrive.cli import main
from diffdrive.encoders import rounding_variance, wheel_quantum
from diffdrive.estimation import Encoders, EstimatorSettings, Gyro, PoseEstimator, gyro_odometry
from diffdrive.estimation.wheel_turns import LEAST, identify_wheel_turns
from diffdrive.sensor_noise import GyroNoise, WheelNoise
from diffdrive.sensors import EncoderModel, GyroModel, Slip, encoder_readings, gyro_readings

ROBOT = dd.DiffDrive(wheel_radius=0.042, track_width=0.2)
COUNTS = 4096
STEP = 2 * math.pi / COUNTS


def _velocities(t: np.ndarray, ramp: float) -> np.ndarray:
    """The built-in driving history (drive off, weave, turn in place), its change to the
    turn in place spread over ``ramp`` s: rad/s ``(T, 2)``."""
    into = (t >= 16.0) * 1.0 if ramp == 0.0 else np.clip((t - 16.0) / ramp + 0.5, 0.0, 1.0)
    cruise = 8.0 * np.clip(t / 2.0, 0.0, 1.0) * (1 - into)
    weave = (2.0 + 0.2 * t) * np.sin(2.0 * np.pi * t / 8.0) * (1 - into)
    return np.stack([cruise - weave - 4.0 * into, cruise + weave + 4.0 * into], axis=-1)


def _path(ramp: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    fine = dd.simulate(ROBOT, lambda t: _velocities(t, ramp), dt=1e-3, duration=20.0)
    return fine.times[::20], fine.poses[::20]


def _log(k: float, arw: float, seed: int, ramp: float = 1.0, slips=()):
    """Times, wheel-angle increments (rad, whole counts) and the gyro along the path."""
    t, poses = _path(ramp)
    noisy = WheelNoise.symmetric(k)
    model = EncoderModel(ticks_per_revolution=COUNTS, wheel_noise=noisy, slips=tuple(slips))
    counts = encoder_readings(ROBOT, t, poses, model, seed=seed).readings[0]
    noise = GyroNoise(angle_random_walk=arw)
    rates = gyro_readings(ROBOT, t, poses, GyroModel(noise=noise), seed=seed + 100).rates[0]
    return t, np.diff(counts.astype(float), axis=0) * STEP, Gyro(t, rates), poses


def _fit(k, arw, seed, **path):
    t, increments, gyro, _ = _log(k, arw, seed, **path)
    turned = np.diff(gyro.angles(t))
    return identify_wheel_turns(ROBOT, t, increments, turned, arw, gyro.interpolation_variances(t))


@pytest.mark.parametrize(("k", "arw"), [(1e-5, 2e-3), (1e-4, 0.0), (1e-4, 2e-3), (1e-3, 1e-2)])
def test_the_wheels_noise_comes_back_from_their_turn_against_the_gyros(k, arw):
    """Drawn at k, each of three seeds gives k back within 20 %, no window left out."""
    for seed in range(3):
        fit = _fit(k, arw, seed)
        assert fit is not None
        assert fit.noise.left == fit.noise.right
        assert 0.8 * k <= fit.noise.left <= 1.2 * k, (seed, fit.noise.left)
        assert fit.left_out == 0
        assert f"k = {fit.noise.left:.3g} m" in fit.report


def test_a_slip_is_left_out_of_the_fit():
    """The left wheel spinning a third again as far as it rolls for 2 s: its windows are left
    out, and k still comes back within 20 %."""
    k = 1e-4
    slip = Slip(4.0, 6.0, "left", 0.3)
    fit = _fit(k, 2e-3, 0, slips=(slip,))
    assert fit is not None
    assert fit.left_out > 0
    assert 0.8 * k <= fit.noise.left <= 1.2 * k


def test_clean_wheels_have_no_noise_beyond_their_counts():
    """Counts without noise and an ideal gyro: k is 0 (the counts' rounding is the floor)."""
    fit = _fit(0.0, 0.0, 0)
    assert fit is not None
    assert fit.noise.left < 1e-8


def test_too_little_driving_is_not_fitted():
    times = np.arange(LEAST) * 0.02  # LEAST - 1 intervals
    increments = np.full((LEAST - 1, 2), 0.01)
    assert identify_wheel_turns(ROBOT, times, increments, np.zeros(LEAST - 1), 1e-3) is None


def test_the_counters_step_is_found_in_their_angles():
    rng = np.random.default_rng(0)
    counts = rng.integers(-40, 40, size=(200, 2))
    assert wheel_quantum(counts * STEP) == pytest.approx(STEP, rel=1e-12)
    # never a single count: the smallest move is two of them
    assert wheel_quantum((2 * counts + 3 * (counts % 2 == 0)) * STEP) == pytest.approx(STEP)
    assert wheel_quantum(rng.normal(size=(200, 2))) is None  # angles that are not counts
    assert wheel_quantum(np.zeros((200, 2))) is None
    assert wheel_quantum(counts[:4] * STEP) is None  # too few moves to tell


def test_the_floor_is_the_rounding_of_two_readings():
    assert Encoders(ticks_per_revolution=COUNTS).wheel_floor == pytest.approx(STEP**2 / 6)
    assert rounding_variance(COUNTS) == Encoders(ticks_per_revolution=COUNTS).wheel_floor
    assert Encoders().wheel_floor == 0.0


def test_a_counter_that_did_not_move_is_no_exact_zero():
    """The first interval reads no count while the gyro turns 2e-4 rad: with the counts'
    floor the bias takes less of it than with none (where the wheels' turn read as exact)."""
    biases = []
    for counts in (None, COUNTS):
        settings = EstimatorSettings(
            wheel_noise=1e-4, encoders=Encoders(ticks_per_revolution=counts)
        )
        estimator = PoseEstimator(ROBOT, settings, initial_time=0.0)
        estimator.update_increments(0.0, 0.0, 0.02, gyro_angle=2e-4)
        biases.append(estimator.state[3])
    exact, floored = biases
    assert 0.0 < floored < 0.8 * exact


def test_the_interpolation_of_a_stepping_rate():
    """A rate that steps from 0 to 1 rad/s at 1 s, sampled every 0.1 s: each span's variance
    is (0.1 x its change)^2 / 12; intervals of two spans each take the spans they hold, and
    an interval cut inside a span takes its part's."""
    times = np.round(np.arange(0.0, 2.01, 0.1), 12)
    rates = np.where(times >= 1.0, 1.0, 0.0)
    rates[10] = 0.5  # the sample at the step reads half-way, as a sampled gyro would
    gyro = Gyro(times, rates)
    each = (0.1 * 0.5) ** 2 / 12
    at = np.round(np.arange(0.0, 2.01, 0.1), 12)
    spans = gyro.interpolation_variances(at)
    expected = np.zeros(20)
    expected[9] = expected[10] = each
    np.testing.assert_allclose(spans, expected, rtol=1e-12, atol=1e-18)
    pairs = gyro.interpolation_variances(at[::2])
    np.testing.assert_allclose(pairs, [0, 0, 0, 0, each, each, 0, 0, 0, 0], atol=1e-18)
    cut = gyro.interpolation_variances(np.array([0.0, 0.95, 2.0]))
    inside = (0.05 * 0.5) ** 2 / 12
    np.testing.assert_allclose(cut, [inside, inside + each], rtol=1e-12)
    # from yaw, exact at its stamps: a whole span adds nothing
    yaw = Gyro.from_yaw(times, np.cumsum(rates) * 0.1)
    assert np.all(yaw.interpolation_variances(at) == 0.0)
    assert yaw.interpolation_variances(np.array([0.0, 0.95, 2.0]))[0] > 0.0


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-3.0, 3.0), min_size=3, max_size=30), st.integers(1, 4))
def test_coarser_intervals_hold_the_same_spans(rates, every):
    """Wheel intervals on the gyro's own stamps, or every ``every`` of them: each coarse
    interval's variance is the sum of the fine ones it holds, and none is negative."""
    times = np.arange(len(rates)) * 0.01
    gyro = Gyro(times, np.array(rates))
    fine = gyro.interpolation_variances(times)
    assert np.all(fine >= 0.0)
    at = times[::every]
    coarse = gyro.interpolation_variances(at)
    sums = np.add.reduceat(fine[: (len(at) - 1) * every], np.arange(0, len(at) - 1) * every)
    np.testing.assert_allclose(coarse, sums, rtol=1e-12, atol=1e-18)


@pytest.mark.parametrize("ramp", [0.0, 0.2, 1.0])
def test_the_fused_heading_is_no_worse_than_the_wheels_on_a_clean_log(ramp):
    """Whole counts of 4,096 a turn and an ideal gyro, the turn in place reached at once
    (0 s: the built-in history, whose rate steps) or over 0.2 s or 1 s: the default fused
    heading's largest error is at most the wheels' own (it was 40 times theirs, 0.77 against
    0.018 degrees, with the wheels' noise at its default)."""
    t, increments, gyro, poses = _log(0.0, 0.0, 0, ramp)
    errors = {}
    for heading in ("wheels", "fused"):
        result = gyro_odometry(ROBOT, t, increments, gyro, EstimatorSettings(heading))
        gap = np.angle(np.exp(1j * (result.poses[:, 2] - poses[:, 2])))
        errors[heading] = np.degrees(np.max(np.abs(gap)))
    assert errors["wheels"] < 0.02
    assert errors["fused"] <= errors["wheels"]


def test_the_command_says_what_it_identified(tmp_path, monkeypatch, capsys):
    """synth's own log with 4,096-count encoders and no noise: odometry's fused heading is no
    worse than its wheels' (0.0176 against 0.0178 degrees; it was 0.77 against 0.018), and it
    says where the wheels' noise and its floor came from."""
    pytest.importorskip("rosbags")
    monkeypatch.chdir(tmp_path)
    assert (
        main(["synth", "-q", "--ticks-per-revolution", "4096", "--seed", "1", "-o", "run.mcap"])
        == 0
    )
    joints = ["--joints", "left_wheel_joint", "right_wheel_joint", "--gyro-topic", "/imu/data"]
    truth = ["--truth", "run.mcap", "--truth-topic", "/ground_truth", "--json"]
    worst = {}
    for heading in ("wheels", "fused"):
        capsys.readouterr()
        assert (
            main(["odometry", "run.mcap", *joints, "--heading", heading, "-o", f"{heading}.csv"])
            == 0
        )
        said = capsys.readouterr().out
        assert "whole steps of 0.001534 rad (4096 counts per revolution)" in said
        assert "from their turn against the gyro's over 1000 intervals" in said
        assert main(["evaluate", f"{heading}.csv", *truth]) == 0
        worst[heading] = json.loads(capsys.readouterr().out)["max_heading_error_deg"]
    assert worst["fused"] <= worst["wheels"] < 0.02
    assert (worst["fused"], worst["wheels"]) == pytest.approx((0.0176, 0.0178), abs=1e-4)
    # given, the wheels' noise is taken as it is and not identified
    assert main(["odometry", "run.mcap", *joints, "--k", "1e-4", "-o", "given.csv"]) == 0
    assert "from their turn against the gyro's" not in capsys.readouterr().out


@pytest.mark.parametrize("core", ["PoseEstimator", "_PythonPoseEstimator"])
def test_a_stream_of_rates_weighs_their_interpolation_as_a_whole_log_does(core):
    """A streaming estimator given the gyro's rate with each wheel reading takes the turn
    between two rates, and how far they leave it open, as a whole log of the same samples
    does: the two end in the same state (the wheels' noise given, as a stream cannot fit it)."""
    from diffdrive.estimation import Window, estimate_trajectory, fusion

    t, increments, gyro, _ = _log(1e-5, 2e-3, 7, ramp=0.0)
    settings = EstimatorSettings(wheel_noise=1e-5, encoders=Encoders(ticks_per_revolution=COUNTS))
    settings = settings.replace(gyro_noise=GyroNoise(angle_random_walk=2e-3), bias=0.0)
    whole = estimate_trajectory(ROBOT, t, increments, gyro=gyro, settings=settings, smooth=False)
    stream = getattr(fusion, core)(ROBOT, settings.replace(window=Window(math.inf, 0.0)),
                                   initial_time=float(t[0]))  # fmt: skip
    stream.update_increments(0.0, 0.0, float(t[0]), gyro_rate=float(gyro.rates[0]))
    for k in range(1, len(t)):
        stream.update_increments(*increments[k - 1], float(t[k]), gyro_rate=float(gyro.rates[k]))
    np.testing.assert_allclose(stream.state, whole.states[-1], rtol=1e-9, atol=1e-11)
    assert np.count_nonzero(gyro.interpolation_variances(t)) > 0.9 * (len(t) - 1)


@pytest.mark.parametrize("core", ["PoseEstimator", "_PythonPoseEstimator"])
def test_rates_whose_interpolation_passes_the_floats_are_refused_and_change_nothing(core):
    """Two rates 1e300 rad/s apart: their interpolation's variance passes the largest float,
    and both cores refuse the reading by name, the estimator as it was."""
    from diffdrive.estimation import fusion

    stream = getattr(fusion, core)(ROBOT, EstimatorSettings("gyro", bias=0.0), initial_time=0.0)
    stream.update_increments(0.0, 0.0, 0.0, gyro_rate=0.0)
    stream.update_increments(0.1, 0.1, 0.02, gyro_rate=0.1)
    before = (stream.state.copy(), stream.state_covariance.copy())
    with pytest.raises(ValueError, match="overflow the state; refused"):
        stream.update_increments(0.2, 0.2, 0.04, gyro_rate=1e300)
    np.testing.assert_array_equal(stream.state, before[0])
    np.testing.assert_array_equal(stream.state_covariance, before[1])
