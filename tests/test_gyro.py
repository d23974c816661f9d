"""Gyro-aided odometry and slip detection: synthetic runs with known slip and gyro errors,
the noise models' checks, and bad input."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import diffdrive as dd
from diffdrive.estimation import EstimatorSettings as S
from diffdrive.estimation import SlipTest
from diffdrive.estimation.gyro import (
    Gyro,
    GyroNoise,
    GyroOdometry,
    gyro_odometry,
    rotation_from_rpy,
)
from diffdrive.sensor_noise import DEFAULT, DEFAULT_GYRO

ROBOT = dd.DiffDrive(wheel_radius=0.05, track_width=0.3)
DT = 0.02
SLIP_STARTS = (600, 1400, 2200)


def slipping_run(seed=0, bias_drift=0.02):
    """A 60 s run: 1 s standing still, then weaving; the left wheel spins 0.25 rad a step
    faster than the ground moves in three 0.5 s episodes; a 100 Hz gyro with a bias that
    drifts from 0.01 rad/s by ``bias_drift`` and white noise."""
    rng = np.random.default_rng(seed)
    n = 3000
    t = np.arange(n + 1) * DT
    wheels = np.stack([6 + 2 * np.sin(0.3 * t[:-1]), 6 - 2 * np.sin(0.21 * t[:-1] + 1)], -1)
    wheels[:50] = 0.0
    truth = dd.simulate(ROBOT, wheels, dt=DT)
    measured = wheels * DT
    slip = np.zeros(n, dtype=bool)
    for start in SLIP_STARTS:
        slip[start : start + 25] = True
    measured[slip, 0] += 0.25
    measured[50:] += rng.normal(0, 0.002, measured[50:].shape)
    gyro_times = np.arange(0, t[-1] + 1e-9, 0.01)
    rates = np.concatenate([truth.twists[:, 2], truth.twists[-1:, 2]])
    yaw_rate = np.interp(gyro_times, truth.times, rates)
    bias = 0.01 + bias_drift * gyro_times / gyro_times[-1]
    gyro = Gyro(gyro_times, yaw_rate + bias + rng.normal(0, 0.02, len(gyro_times)))
    return t, measured, gyro, truth, slip


def errors(result, truth):
    return np.hypot(*(result.poses[:, :2] - truth.poses[:, :2]).T)


def test_fused_beats_the_wheels_and_the_gyro_alone():
    t, measured, gyro, truth, _ = slipping_run()
    found = {
        heading: errors(
            gyro_odometry(ROBOT, t, measured, gyro, S(heading, wheel_noise=2e-6)), truth
        ).max()
        for heading in ("wheels", "gyro", "fused")
    }
    # measured: wheels 13.2 m (slip turns them), gyro 2.36 m (its bias drifts), fused 0.44 m
    assert found["fused"] < 0.6
    assert found["gyro"] > 2 * found["fused"]
    assert found["wheels"] > 10 * found["fused"]


def test_slip_detection_rate_and_false_alarms_at_the_default_threshold():
    rates = []
    for seed in range(3):
        t, measured, gyro, _, slip = slipping_run(seed)
        result = gyro_odometry(ROBOT, t, measured, gyro, S(wheel_noise=2e-6))
        flagged = result.slip[1:]
        rates.append((flagged[slip].mean(), flagged[~slip].mean()))
    detection, false_alarm = np.mean(rates, axis=0)
    assert detection == 1.0  # every slipping interval (75 per run)
    assert false_alarm < 0.003  # chi-square(1) at 10.83: 0.1 % nominal; measured 0.07-0.1 %
    assert not result.slip[0]


def test_the_fused_bias_follows_a_drifting_bias():
    t, measured, gyro, _, _ = slipping_run()
    result = gyro_odometry(ROBOT, t, measured, gyro, S(wheel_noise=2e-6))
    assert result.bias[0] == pytest.approx(0.01, abs=2e-3)  # from the first second, standing
    assert result.bias[-1] > 0.018  # the true bias ends at 0.03 rad/s; a fixed one stays 0.01


def test_with_a_perfect_gyro_and_wheels_every_heading_gives_the_truth():
    t = np.arange(201) * DT
    wheels = np.tile([5.0, 7.0], (200, 1))
    truth = dd.simulate(ROBOT, wheels, dt=DT)
    gyro = Gyro(t, np.full(201, truth.twists[0, 2]))
    for heading in ("wheels", "gyro", "fused"):
        result = gyro_odometry(ROBOT, t, wheels * DT, gyro, S(heading, bias=0.0))
        np.testing.assert_allclose(result.poses, truth.poses, atol=1e-9)
        assert not result.slip.any()


def test_streaming_equals_the_whole_log(monkeypatch):
    """The streaming filter (the C core where built) and the whole log (the Python core):
    equal to rounding, given the same gyro and wheel noise (the whole log would otherwise
    identify its own) and with the one thing a stream given angles cannot know left out: how
    far the gyro's samples leave each turn open."""
    monkeypatch.setattr(Gyro, "interpolation_variances", lambda self, at: np.zeros(len(at) - 1))
    t, measured, gyro, _, _ = slipping_run()
    noise = DEFAULT_GYRO
    settings = S("fused", wheel_noise=DEFAULT, bias=0.01, gyro_noise=noise)
    whole = gyro_odometry(ROBOT, t[:300], measured[:299], gyro, settings)
    streaming = GyroOdometry(ROBOT, settings)
    turned, steps = np.diff(gyro.angles(t[:300])), np.diff(t[:300])
    for k in range(299):
        streaming.update(*measured[k], turned[k], steps[k])
    np.testing.assert_allclose(streaming.state[:3], whole.poses[-1], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(streaming.covariance, whole.covariances[-1], rtol=1e-10, atol=1e-18)


def test_covariance_is_symmetric_positive_and_grows_with_distance():
    t, measured, gyro, _, _ = slipping_run()
    result = gyro_odometry(ROBOT, t, measured, gyro, S(wheel_noise=2e-6))
    for covariance in result.covariances[::300]:
        np.testing.assert_allclose(covariance, covariance.T, atol=1e-15)
        assert np.linalg.eigvalsh(covariance).min() > -1e-12
    assert result.covariances[-1, 0, 0] > result.covariances[500, 0, 0]


def test_imu_mounting_rotates_the_rates_into_the_body():
    times = np.arange(5) * 0.1
    rates = np.array([[0.0, 0.3, 0.0]] * 5)  # the yaw on the IMU's y axis (the Husky's trap)
    assert np.allclose(Gyro.from_imu(times, rates).rates, 0.0)
    mounted = Gyro.from_imu(times, rates, rotation_from_rpy(math.pi / 2, 0.0, 0.0))
    np.testing.assert_allclose(mounted.rates, 0.3)
    yaw = Gyro.from_yaw(times, np.array([3.0, 3.1, -3.1, -3.0, -2.9]))  # through the wrap
    np.testing.assert_allclose(yaw.rates[:-1], [1.0, (2 * math.pi - 6.2) / 0.1, 1.0, 1.0])
    np.testing.assert_allclose(
        Gyro(times, np.full(5, 2.0)).angles(np.array([0.05, 0.4])), [0.1, 0.8]
    )


def test_a_yaw_comes_back_at_its_own_stamps():
    """Gyro.from_yaw's angles are the yaw given (less its first), not the mean of each
    interval's rate and the next one's ([0, 0.5, 0.5, 0.5] before)."""
    t = np.arange(4.0)
    gyro = Gyro.from_yaw(t, [0.0, 1.0, 1.0, 1.0])
    np.testing.assert_array_equal(gyro.angles(t), [0.0, 1.0, 1.0, 1.0])
    np.testing.assert_allclose(gyro.angles([0.5, 1.5, 2.25]), [0.5, 1.0, 1.0])  # rate held


@settings(max_examples=60)
@given(
    steps=st.lists(st.floats(1e-3, 0.5), min_size=1, max_size=40),
    turns=st.lists(st.floats(-3.0, 3.0), min_size=40, max_size=40),
    start=st.floats(-10.0, 10.0),
)
def test_any_yaw_comes_back_exactly_and_linear_between(steps, turns, start):
    times = np.concatenate([[0.0], np.cumsum(steps)])
    yaw = start + np.concatenate([[0.0], np.cumsum(turns[: len(steps)])])
    gyro = Gyro.from_yaw(times, yaw)
    np.testing.assert_array_equal(gyro.angles(times), yaw - yaw[0])
    middle = 0.5 * (times[1:] + times[:-1])
    expected = 0.5 * ((yaw[1:] - yaw[0]) + (yaw[:-1] - yaw[0]))
    # Linear to rounding: a stamp's ulp over a short step, times the step's turn.
    scale = 1.0 + float(np.abs(yaw).max())
    np.testing.assert_allclose(gyro.angles(middle), expected, rtol=0, atol=1e-10 * scale)


def test_a_wrapped_yaw_is_unwrapped_before_it_comes_back():
    t = np.arange(5) * 0.1
    wrapped = np.array([3.0, 3.1, -3.1, -3.0, -2.9])
    np.testing.assert_allclose(Gyro.from_yaw(t, wrapped).angles(t), np.unwrap(wrapped) - 3.0)


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (
            lambda: Gyro.from_imu([0, 1], np.zeros((2, 3)), np.diag([1.0, 1.0, -1.0])),
            "mounting is not a rotation",
        ),
        (
            lambda: Gyro.from_imu([0, 1], np.zeros((2, 3)), 2 * np.eye(3)),
            "mounting is not a rotation",
        ),
        (lambda: Gyro([0.0, 1.0, 1.0], [0.0, 0.0, 0.0]), "gyro times must increase"),
        (
            lambda: Gyro([0.0, 0.1, 5.0], [0.0, 0.0, 0.0], max_gap=1.0),
            "the gyro stream stops for 4.9 s after t = 0.1 s",
        ),
        (lambda: Gyro([0.0, 1.0], [0.0, math.nan]), "must be finite"),
        (
            lambda: Gyro([0.0, 1.0], [0.0, 0.0]).angles(np.array([0.5, 1.5])),
            r"the wheel log spans \[0.5, 1.5\] s, the gyro only \[0, 1\] s",
        ),
        (lambda: SlipTest(threshold=-1.0), r"SlipTest\.threshold must be > 0"),
        (lambda: S(heading="compass"), "heading must be one of"),  # type: ignore[arg-type]
        (lambda: GyroNoise(angle_random_walk=-1.0), "angle_random_walk must be >= 0"),
        (
            lambda: gyro_odometry(
                ROBOT, [0.0, 1.0], np.ones((1, 2)), Gyro([0.0, 1.0], [0.0, 0.0]), S("gyro")
            ),
            "heading 'gyro' needs the gyro bias",
        ),
    ],
)
def test_bad_gyro_input_is_refused(make, message):
    with pytest.raises(ValueError, match=message):
        make()


def test_a_refused_update_changes_nothing():
    odometry = GyroOdometry(ROBOT, S("fused"))
    odometry.update(0.1, 0.12, 0.01, 0.02)
    before = (odometry.state.copy(), odometry.covariance4.copy(), odometry.slip)
    for args in ((math.nan, 0.1, 0.0, 0.02), (0.1, 0.1, 0.0, 0.0), (1e300, 1e300, 0.0, 0.02)):
        with pytest.raises(ValueError):
            odometry.update(*args)
        np.testing.assert_array_equal(odometry.state, before[0])
        np.testing.assert_array_equal(odometry.covariance4, before[1])


def test_the_command_line_takes_a_gyro_column_and_writes_slip_columns(tmp_path, capsys):
    from diffdrive.cli import main

    t, measured, gyro, _, slip = slipping_run()
    angles = np.vstack([[0.0, 0.0], np.cumsum(measured, axis=0)])
    rates = np.interp(t, gyro.times, gyro.rates)
    log = tmp_path / "log.csv"
    rows = "\n".join(
        f"{a!r},{b!r},{c!r},{d!r}"
        for a, (b, c), d in zip(t.tolist(), angles.tolist(), rates.tolist(), strict=True)
    )
    log.write_text("t,left_angle,right_angle,gyro_z\n" + rows + "\n")
    out = tmp_path / "o.csv"
    argv = [
        "odometry",
        str(log),
        "--wheel-radius",
        "0.05",
        "--track-width",
        "0.3",
        "--k-left",
        "2e-6",
        "--k-right",
        "2e-6",
        "-o",
        str(out),
    ]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "slip: " in printed
    table = np.genfromtxt(out, delimiter=",", names=True)
    assert set(table.dtype.names) >= {"slip", "slip_score", "gyro_bias"}
    assert table["slip"][1:][slip].mean() > 0.9
    alone = tmp_path / "alone.csv"
    assert main([*argv[:-1], str(alone), "--slip-test", "interval", "-q"]) == 0
    flags = np.genfromtxt(alone, delimiter=",", names=True)["slip"].astype(bool)
    assert not np.any(flags & ~table["slip"].astype(bool))  # the episodes add, never take
    plain = tmp_path / "plain.csv"
    plain.write_text("t,left_angle,right_angle\n0,0,0\n1,1,1\n")
    assert main(["odometry", str(plain), "--heading", "fused", "-o", str(out)]) == 1
    assert "--heading fused needs a gyro" in capsys.readouterr().err
    code = main(
        ["odometry", str(log), "--heading", "gyro", "--gyro-bias", "0.01", "-o", str(out), "-q"]
    )
    assert code == 0


def test_commanded_wheel_velocities_flag_a_wheel_that_spins_up_beyond_its_command():
    """A gyro that cannot see it: the slip turns the robot as the ground does (both wheels
    spin up together), but the drives were commanded otherwise."""
    t = np.arange(301) * DT
    wheels = np.tile([6.0, 6.0], (300, 1))
    measured = wheels * DT
    spin = np.zeros(300, dtype=bool)
    spin[100:120] = True
    measured[spin] *= 1.5  # both wheels spin 50 % faster than commanded, straight ahead
    gyro = Gyro(t, np.zeros(301))
    result = gyro_odometry(
        ROBOT, t, measured, gyro, S(bias=0.0, slip=SlipTest(command_sigma=0.5)), commanded=wheels
    )
    flagged = result.slip[1:]
    assert flagged[spin].all()
    assert not flagged[~spin].any()
    without = gyro_odometry(ROBOT, t, measured, gyro, S(bias=0.0))
    assert not without.slip.any()  # the gyro alone sees nothing: no turn
    assert result.covariances[-1, 0, 0] > without.covariances[-1, 0, 0]  # inflated travel
    with pytest.raises(ValueError, match=r"commanded must be \(300, 2\)"):
        gyro_odometry(ROBOT, t, measured, gyro, S(bias=0.0), commanded=wheels[:5])


def test_the_command_line_reads_command_columns(tmp_path, capsys):
    from diffdrive.cli import main

    t = np.arange(301) * DT
    measured = np.tile([6.0, 6.0], (300, 1)) * DT
    measured[100:120] *= 1.5
    angles = np.vstack([[0.0, 0.0], np.cumsum(measured, axis=0)])
    rows = "\n".join(
        f"{a!r},{b!r},{c!r},0.0,6.0,6.0"
        for a, (b, c) in zip(t.tolist(), angles.tolist(), strict=True)
    )
    log = tmp_path / "log.csv"
    log.write_text("t,left_angle,right_angle,gyro_z,left_command,right_command\n" + rows + "\n")
    out = tmp_path / "o.csv"
    assert (
        main(
            [
                "odometry",
                str(log),
                "--wheel-radius",
                "0.05",
                "--track-width",
                "0.3",
                "--gyro-bias",
                "0",
                "-o",
                str(out),
            ]
        )
        == 0
    )
    assert "slip: 20 of 300 intervals flagged" in capsys.readouterr().out
    # The estimator's path (a smoother) takes the commands too.
    common = ["--wheel-radius", "0.05", "--track-width", "0.3", "--gyro-bias", "0"]
    smoothed = tmp_path / "s.csv"
    assert main(["odometry", str(log), *common, "--smooth", "-o", str(smoothed), "-q"]) == 0
    header = smoothed.read_text().splitlines()[0].split(",")
    flags = np.loadtxt(smoothed, delimiter=",", skiprows=1, usecols=header.index("slip"))
    assert np.flatnonzero(flags).tolist() == list(range(101, 121))


def test_the_exact_heading_as_yaw_flags_no_slip_and_follows_the_wheels():
    """A 500-interval log whose yaw is the path's own heading: no interval slips, and the
    gyro heading's path is the wheels' (436 flags and 1.5 m apart before)."""
    robot = dd.DiffDrive(0.05, 0.3)
    t = np.arange(501) * 0.02
    wheels = np.stack([6 + 4 * np.sin(0.7 * t[:-1]), 6 - 4 * np.cos(0.5 * t[:-1])], axis=-1)
    path = dd.simulate(robot, wheels, times=t)
    increments = wheels * 0.02
    gyro = Gyro.from_yaw(t, path.poses[:, 2])
    result = gyro_odometry(robot, t, increments, gyro, S("gyro", bias=0.0))
    assert not result.slip.any()
    np.testing.assert_allclose(result.poses, path.poses, atol=1e-9)
