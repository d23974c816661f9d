"""Synthetic sensors: ideal streams give their trajectory back, each error source has the
statistics its model states, and the estimators meet what they were built for."""

import dataclasses
import importlib.util
import math

import numpy as np
import pytest

import diffdrive as dd
from diffdrive import sensors
from diffdrive.estimation import EstimatorSettings, WholeLog
from diffdrive.estimation.gyro import Gyro, gyro_odometry
from diffdrive.sensor_noise import DEFAULT_GYRO, GyroNoise
from diffdrive.simulation import dead_reckon

ROBOT = dd.DiffDrive(0.05, 0.3, axle_offset=0.02)
SKID = dd.SkidSteer(0.11, 0.45, -0.40, icr_x=0.03)
T = np.arange(501) * 0.02
WHEELS = np.stack([6 + 4 * np.sin(0.7 * T[:-1]), 6 - 4 * np.cos(0.5 * T[:-1])], axis=-1)


def path(robot=ROBOT):
    return dd.simulate(robot, WHEELS, times=T)


@pytest.mark.parametrize("robot", [ROBOT, SKID], ids=["diff drive", "skid steer"])
def test_ideal_encoders_give_the_wheels_back_and_the_path_through_a_run(robot):
    trajectory = path(robot)
    readings = sensors.encoder_readings(robot, trajectory.times, trajectory.poses)
    np.testing.assert_allclose(np.diff(readings.readings[0], axis=0), WHEELS * 0.02, atol=1e-12)
    run = readings.run(0)
    assert run.kind == "angle"
    poses = dead_reckon(robot, run.increments(), run.truth[0])
    np.testing.assert_allclose(poses, trajectory.poses, atol=1e-12)
    commands = sensors.commands_of(robot, trajectory.times, trajectory.poses)
    np.testing.assert_allclose(commands.wheels[0], WHEELS, atol=1e-11)
    np.testing.assert_allclose(commands.twists[0], trajectory.twists, atol=1e-11)


@pytest.mark.parametrize(("bits", "signed"), [(12, True), (10, False), (64, False), (None, True)])
def test_counts_roll_over_and_odometry_reads_them_back(bits, signed):
    model = sensors.EncoderModel(ticks_per_revolution=4096, counter_bits=bits, signed=signed)
    trajectory = path()
    readings = sensors.encoder_readings(ROBOT, T, trajectory.poses, model)
    counts = readings.readings[0]
    if bits is not None and bits < 64:
        low, high = (-(2 ** (bits - 1)), 2 ** (bits - 1) - 1) if signed else (0, 2**bits - 1)
        assert counts.min() >= low
        assert counts.max() <= high
        assert counts.max() - counts.min() > 2 ** (bits - 1)  # it did roll over
    assert counts.dtype == (np.uint64 if bits == 64 and not signed else np.int64)
    odometry = dd.Odometry(
        ROBOT,
        ticks_per_revolution=4096,
        counter_bits=bits,
        initial_pose=dd.Pose(*trajectory.poses[0]),
    )
    poses, _ = odometry.update_arrays("ticks", counts[:, 0], counts[:, 1], T)
    # One count is 1.5 mrad of wheel, 77 um at the rim: the path within a millimetre.
    assert np.abs(poses[:, :2] - trajectory.poses[:, :2]).max() < 1e-3


def test_biases_make_the_nominal_odometry_drift_as_calibration_would_undo():
    model = sensors.EncoderModel(radius_bias=(0.02, -0.01), track_bias=0.03)
    trajectory = path()
    readings = sensors.encoder_readings(ROBOT, T, trajectory.poses, model)
    np.testing.assert_allclose(readings.geometry[0], [0.051, 0.0495, 0.309])
    increments = np.diff(readings.readings[0], axis=0)
    true_robot = dd.DiffDrive(
        left_wheel_radius=0.051, right_wheel_radius=0.0495, track_width=0.309, axle_offset=0.02
    )
    np.testing.assert_allclose(
        dead_reckon(true_robot, increments, trajectory.poses[0]), trajectory.poses, atol=1e-9
    )
    drift = dead_reckon(ROBOT, increments, trajectory.poses[0]) - trajectory.poses
    assert np.abs(drift[:, :2]).max() > 0.05


def test_wheel_noise_matches_the_odometry_covariance_it_is_modelled_on():
    """10^4 robots with wheel random-walk noise only: the final poses' sample covariance is
    Odometry's propagated one, trace and each diagonal term within 5 %."""
    k = (2e-4, 4e-4)
    steps = 100
    trajectory = dd.simulate(ROBOT, WHEELS[:steps], times=T[: steps + 1])
    model = sensors.EncoderModel(wheel_noise=(k[0], k[1]))
    readings = sensors.encoder_readings(
        ROBOT, trajectory.times, trajectory.poses, model, robots=10_000, seed=7
    )
    start = trajectory.poses[0]
    finals = dead_reckon(ROBOT, np.diff(readings.readings, axis=1), start)[:, -1]
    sample = np.cov(finals.T)
    odometry = dd.Odometry(ROBOT, initial_pose=dd.Pose(*start), wheel_noise=(k[0], k[1]))
    odometry.update_arrays("increments", *(WHEELS[:steps] * 0.02).T)
    propagated = odometry.covariance
    assert np.trace(sample) == pytest.approx(np.trace(propagated), rel=0.05)
    np.testing.assert_allclose(np.diag(sample), np.diag(propagated), rtol=0.05)


def slip_flags(model, k, arw, robots, seeds, slip_episodes=True):
    """Each robot's labelled slipping intervals and the gyro filter's flags, ``(robots, T-1)``:
    encoders from ``model``, a gyro with angle random walk ``arw``, the filter told both."""
    trajectory = path()
    readings = sensors.encoder_readings(
        ROBOT, T, trajectory.poses, model, robots=robots, seed=seeds[0]
    )
    gyro = sensors.gyro_readings(
        ROBOT,
        T,
        trajectory.poses,
        sensors.GyroModel(noise=GyroNoise(angle_random_walk=arw)),
        robots=robots,
        seed=seeds[1],
    )
    flags = [
        gyro_odometry(
            ROBOT,
            T,
            np.diff(readings.readings[n], axis=0),
            Gyro(T, gyro.rates[n]),
            EstimatorSettings(
                bias=0.0,
                wheel_noise=k,
                gyro_noise=dataclasses.replace(DEFAULT_GYRO, angle_random_walk=arw),
                whole_log=WholeLog(slip_episodes=slip_episodes),
            ),
        ).slip[1:]
        for n in range(robots)
    ]
    return readings.slipping.any(axis=-1), np.array(flags)


def test_slips_are_labelled_and_the_gyro_filter_finds_them():
    """A wheel spinning half again as far as the ground moves over three episodes: the
    detector flags the labelled intervals (README: what it finds) and few others."""
    slips = tuple(sensors.Slip(s, s + 0.4, "left", 0.5) for s in (2.0, 5.0, 8.0))
    model = sensors.EncoderModel(wheel_noise=1e-6, slips=slips)
    labelled, flagged = slip_flags(model, 1e-6, 1e-3, 20, (3, 4))
    assert labelled[0].sum() == 60  # 3 episodes of 20 intervals
    assert flagged[labelled].mean() >= 0.99
    assert flagged[~labelled].mean() <= 0.005


def test_the_whole_log_finds_slips_too_weak_for_one_interval():
    """Noisier wheels and gyro (the README's run): a left wheel spinning half again as far
    while it turns slowest moves each interval's turn by about 3 standard deviations, which
    the streaming test alone passes about half the time; the episodes find the whole slip."""
    slips = (sensors.Slip(1.0, 1.4, "right", 0.5), sensors.Slip(6.4, 6.8, "left", 0.5))
    model = sensors.EncoderModel(wheel_noise=1e-5, slips=slips)
    labelled, alone = slip_flags(model, 1e-5, 2e-3, 20, (5, 6), slip_episodes=False)
    _, pooled = slip_flags(model, 1e-5, 2e-3, 20, (5, 6))
    assert alone[labelled].mean() < 0.9  # measured 0.43
    assert pooled[labelled].mean() >= 0.99  # 0.995
    assert pooled[~labelled].mean() <= 0.003  # 0.0027, most beside the slips


def test_a_wheel_radius_error_is_the_geometry_not_a_slip():
    """A left wheel 5 % large turns the wheels' turn away from the gyro's on every interval:
    pooled over a log that is as clear as a slip, but it is the geometry's error (without
    the steady fit, 5.8 % of the intervals were flagged)."""
    model = sensors.EncoderModel(radius_bias=(0.05, 0.0), wheel_noise=1e-5)
    _, flagged = slip_flags(model, 1e-5, 2e-3, 5, (7, 8))
    assert flagged.mean() < 0.005


def test_jitter_latency_and_drops():
    trajectory = path()
    late = sensors.encoder_readings(
        ROBOT, T, trajectory.poses, sensors.EncoderModel(latency=0.1), seed=1
    )
    ideal = sensors.encoder_readings(ROBOT, T, trajectory.poses)
    np.testing.assert_allclose(late.readings[0, 5:], ideal.readings[0, :-5], atol=1e-12)
    np.testing.assert_array_equal(late.readings[0, :5], 0.0)  # before the start: the start
    jitter = sensors.encoder_readings(
        ROBOT, T, trajectory.poses, sensors.EncoderModel(jitter=0.002), seed=1
    )
    speed = np.abs(WHEELS).max()
    assert np.abs(jitter.readings - ideal.readings).max() < 5 * 0.002 * speed
    dropped = sensors.encoder_readings(
        ROBOT, T, trajectory.poses, sensors.EncoderModel(drop=0.2), robots=50, seed=2
    )
    assert dropped.kept[:, 0].all()
    assert dropped.kept.mean() == pytest.approx(0.8, abs=0.02)
    run = dropped.run(3)
    assert len(run.times) == dropped.kept[3].sum()


def test_seeds_repeat_and_differ():
    model = sensors.EncoderModel(wheel_noise=1e-4, geometry_sigma=(0.01, 0.01, 0.02))
    poses = path().poses
    one, two, other = (
        sensors.encoder_readings(ROBOT, T, poses, model, robots=4, seed=s) for s in (5, 5, 6)
    )
    np.testing.assert_array_equal(one.readings, two.readings)
    assert not np.array_equal(one.readings, other.readings)
    assert len({tuple(g) for g in one.geometry}) == 4


def test_gyro_noise_has_the_stated_statistics_and_reads_back_through_the_imu():
    """White rate noise of arw / sqrt(dt); a rate random walk whose variance grows as
    rrw^2 t; a constant bias and scale; the mounting's three rates back to the yaw rate."""
    poses = path().poses
    dt = 0.02
    white = sensors.gyro_readings(
        ROBOT,
        T,
        poses,
        sensors.GyroModel(noise=GyroNoise(angle_random_walk=2e-3)),
        robots=200,
        seed=1,
    )
    noise = white.rates - white.truth
    assert noise.std() == pytest.approx(2e-3 / math.sqrt(dt), rel=0.02)
    walk = sensors.gyro_readings(
        ROBOT,
        T,
        poses,
        sensors.GyroModel(noise=GyroNoise(rate_random_walk=1e-3)),
        robots=4000,
        seed=2,
    )
    assert walk.bias[:, -1].var() == pytest.approx(1e-6 * T[-1], rel=0.1)
    mounting = dd.estimation.rotation_from_rpy(math.pi / 2, 0.0, 0.3)
    model = sensors.GyroModel(bias=0.01, scale=0.02, mounting=mounting)
    fixed = sensors.gyro_readings(ROBOT, T, poses, model)
    np.testing.assert_allclose(fixed.rates, 1.02 * fixed.truth + 0.01, atol=1e-15)
    back = Gyro.from_imu(T, fixed.angular_velocity[0], mounting)
    np.testing.assert_allclose(back.rates, fixed.rates[0], atol=1e-12)
    markov = sensors.gyro_readings(
        ROBOT,
        T,
        poses,
        sensors.GyroModel(noise=GyroNoise(bias_instability=1e-3)),
        robots=4000,
        seed=3,
    )
    assert markov.bias.std(axis=0).mean() == pytest.approx(1e-3, rel=0.05)


def test_absolute_sensors_noise_latency_dropouts_outliers_and_gps():
    pytest.importorskip("pymap3d", reason="pymap3d is in the test group")
    poses = path().poses
    model = sensors.AbsoluteModel(
        sigma=(0.05, 0.05, 0.02), period=0.1, latency=0.25, dropout=0.1, outlier=0.05
    )
    readings = sensors.absolute_readings(ROBOT, T, poses, model, robots=200, seed=4)
    assert readings.times[1] - readings.times[0] == pytest.approx(0.1)
    np.testing.assert_allclose(readings.arrival - readings.times, 0.25)
    error = (readings.poses - readings.truth)[~readings.outliers]
    np.testing.assert_allclose(error.std(axis=0), [0.05, 0.05, 0.02], rtol=0.05)
    assert readings.outliers.mean() == pytest.approx(0.05, abs=0.01)
    jumps = np.hypot(*(readings.poses - readings.truth)[readings.outliers][:, :2].T)
    assert np.median(jumps) == pytest.approx(1.0, abs=0.1)
    assert readings.kept.mean() == pytest.approx(0.9, abs=0.01)
    gps = sensors.absolute_readings(ROBOT, T, poses, sensors.AbsoluteModel(position_only=True))
    assert np.isnan(gps.poses[..., 2]).all()
    geodetic = gps.geodetic((48.0, 11.0, 500.0))
    metres_per_degree = 111_200.0
    north = (geodetic[0, -1, 0] - 48.0) * metres_per_degree
    assert north == pytest.approx(poses[-1, 1], abs=0.5)


def test_a_wandering_receiver_adds_a_random_walk_and_draws_the_rest_the_same():
    """``wander``: each axis's offset starts at zero and steps with variance ``wander^2 dt``;
    the white noise, outliers and dropouts drawn are those of the same receiver without it."""
    poses = path().poses
    plain = sensors.AbsoluteModel(sigma=(0.05, 0.05, 0.0), period=0.1, dropout=0.1, outlier=0.05)
    wandering = dataclasses.replace(plain, wander=0.3)
    base = sensors.absolute_readings(ROBOT, T, poses, plain, robots=300, seed=2)
    moved = sensors.absolute_readings(ROBOT, T, poses, wandering, robots=300, seed=2)
    assert not base.offsets.any()
    np.testing.assert_array_equal(moved.offsets[:, 0], 0.0)
    steps = np.diff(moved.offsets, axis=1)
    assert steps.std() == pytest.approx(0.3 * math.sqrt(0.1), rel=0.02)
    np.testing.assert_allclose(moved.poses[..., :2], base.poses[..., :2] + moved.offsets)
    np.testing.assert_array_equal(moved.kept, base.kept)
    np.testing.assert_array_equal(moved.outliers, base.outliers)
    with pytest.raises(ValueError, match="wander must be >= 0"):
        sensors.AbsoluteModel(wander=-0.1)


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: sensors.EncoderModel(wheel_noise=(-1e-4, 0)), "wheel noise left must be a number"),
        (
            lambda: sensors.EncoderModel(wheel_noise=(0, math.nan)),
            "wheel noise right must be finite",
        ),
        (lambda: sensors.EncoderModel(ticks_per_revolution=100, counter_bits=65), "from 2 to 64"),
        (lambda: sensors.EncoderModel(counter_bits=16), "counter_bits needs ticks_per_revolution"),
        (lambda: sensors.EncoderModel(drop=1.0), "drop must be a probability"),
        (lambda: sensors.Slip(2.0, 1.0), "must end after it starts"),
        (lambda: sensors.Slip(1.0, 2.0, ratio=-1.0), "ratio must be > -1"),
        (
            lambda: sensors.GyroModel(noise=GyroNoise(angle_random_walk=-1.0)),
            "angle_random_walk must be >= 0",
        ),
        (lambda: sensors.GyroModel(mounting=np.diag([1, 1, -1])), "mounting is not a rotation"),
        (lambda: sensors.AbsoluteModel(sigma=(0.1, -0.1, 0.0)), "sigma must be 3"),
        (
            lambda: sensors.encoder_readings(ROBOT, [0.0, 1.0, 0.5], np.zeros((3, 3))),
            r"times must increase: times\[2\] = 0.5 after 1.0",
        ),
        (
            lambda: sensors.encoder_readings(
                ROBOT, T, path().poses, sensors.EncoderModel(slips=(sensors.Slip(9.0, 11.0),))
            ),
            "slip episode 9 to 11 s lies outside the run",
        ),
        (lambda: sensors.encoder_readings(ROBOT, T, np.zeros((501, 2))), "poses must be"),
        (lambda: sensors.encoder_readings(ROBOT, T, path().poses, seed=-1), "seed must be"),
        (lambda: sensors.encoder_readings(ROBOT, T, path().poses, robots=0), "robots must be"),
    ],
)
def test_bad_input_is_refused_by_name(make, message):
    with pytest.raises(ValueError, match=message):
        make()


def test_streams_round_trip_through_a_bag_and_a_table(tmp_path):
    """Written as MCAP and read back by diffdrive's readers (and rosbags under them): the
    joints, the IMU through its mounting, the late poses and the commands; the table reads as
    a Run with its gyro and commands."""
    pytest.importorskip("rosbags", reason="rosbags is in the test group")
    from diffdrive.io import read_run, ros

    trajectory = path()
    encoder_model = sensors.EncoderModel(ticks_per_revolution=4096, counter_bits=12, drop=0.1)
    encoders = sensors.encoder_readings(ROBOT, T, trajectory.poses, encoder_model, seed=1)
    mounting = dd.estimation.rotation_from_rpy(math.pi / 2, 0.0, 0.0)
    gyro = sensors.gyro_readings(
        ROBOT, T, trajectory.poses, sensors.GyroModel(bias=0.01, mounting=mounting), seed=2
    )
    late = sensors.AbsoluteModel(sigma=(0.02, 0.02, 0.01), period=0.5, latency=0.3)
    absolute = sensors.absolute_readings(ROBOT, T, trajectory.poses, late, seed=3)
    commands = sensors.commands_of(ROBOT, T, trajectory.poses)
    bag = sensors.write_bag(
        tmp_path / "run.mcap", encoders=encoders, gyro=gyro, absolute=absolute, commands=commands
    )
    run = ros.read_joint_states(bag, "left_wheel_joint", "right_wheel_joint")
    kept = encoders.kept[0]
    # A stamp of 0 reads as unset in ROS: the streams start 1 s in.
    np.testing.assert_allclose(run.times, T[kept] + 1.0, atol=1e-9)
    angles = np.diff(run.wheels, axis=0)
    np.testing.assert_allclose(angles, encoders.run(0).increments(counter_bits=12), atol=1e-12)
    imu = ros.read_imu(bag, "/imu/data")
    back = Gyro.from_imu(imu.times, imu.angular_velocity, mounting)
    np.testing.assert_allclose(back.rates, gyro.rates[0], atol=1e-12)
    poses = ros.read_odometry(bag, "/pose")
    np.testing.assert_allclose(poses.times, absolute.times + 1.0, atol=1e-9)
    assert poses.stamp_source == "header"  # stamped when measured, recorded 0.3 s later
    np.testing.assert_allclose(poses.poses[:, :2], absolute.poses[0, :, :2], atol=1e-12)
    np.testing.assert_allclose(poses.covariances[0], np.diag([4e-4, 4e-4, 1e-4]))
    recorded = {t.name: t for t in ros.topics(bag)}
    assert recorded["/pose"].msgtype == "geometry_msgs/msg/PoseWithCovarianceStamped"
    twists = ros.read_twists(bag, "/cmd_vel")
    np.testing.assert_allclose(twists.twists, commands.twists[0][:, [0, 2]], atol=1e-12)
    table = sensors.write_table(tmp_path / "run.csv", encoders, gyro=gyro, commands=commands)
    read = read_run(table)
    np.testing.assert_array_equal(read.wheels, encoders.readings[0][kept])
    np.testing.assert_allclose(read.gyro_rates, gyro.rates[0][kept])
    np.testing.assert_allclose(read.truth, trajectory.poses[kept], atol=1e-12)
    assert read.commands is not None


def test_the_synth_command_writes_what_odometry_and_the_readers_take(tmp_path, capsys):
    pytest.importorskip("rosbags", reason="rosbags is in the test group")
    from diffdrive.cli import main
    from diffdrive.io import read_run, ros

    bag, table = tmp_path / "run.mcap", tmp_path / "run.csv"
    common = ["--ticks-per-revolution", "4096", "--counter-bits", "12", "--seed", "1"]
    argv = ["synth", *common, "--gyro", "arw=2e-3", "--pose-sigma", "0.02", "0.02", "0.01"]
    assert main([*argv, "--pose", "period=0.5", "-o", str(bag)]) == 0
    assert "/cmd_vel, /pose, the truth on /ground_truth in" in capsys.readouterr().out
    names = {topic.name for topic in ros.topics(bag)}
    assert names == {"/joint_states", "/imu/data", "/cmd_vel", "/pose", "/ground_truth"}
    assert main(["synth", *common, "-o", str(table), "-q"]) == 0
    run = read_run(table)
    assert run.kind == "ticks"
    joints = ros.read_joint_states(bag, "left_wheel_joint", "right_wheel_joint")
    np.testing.assert_allclose(run.times, joints.times, atol=2e-9)  # the bag's clock
    assert main(["synth", *common, "--time-offset", "5", "-o", str(tmp_path / "late.csv")]) == 0
    assert "the stamps are the trajectory's plus 5 s" in capsys.readouterr().out
    np.testing.assert_allclose(read_run(tmp_path / "late.csv").times, run.times + 4.0)
    assert run.wheels.max() < 2**11
    odometry = tmp_path / "o.csv"
    argv = ["odometry", str(table), "--counter-bits", "12", "-o", str(odometry)]
    assert main([*argv, "--ticks-per-revolution", "4096"]) == 0
    assert "position error max 0.00" in capsys.readouterr().out  # counts alone: mm off
    code = main(["synth", "--slip", "30", "40", "left", "0.5", "-o", str(tmp_path / "x.mcap")])
    assert code == 1
    assert "slip episode 30 to 40 s lies outside the run" in capsys.readouterr().err
    code = main(["synth", "--pose-sigma", "0.1", "0.1", "0.1", "-o", str(tmp_path / "x.csv")])
    assert code == 1
    assert "a pose or GPS sensor needs a bag" in capsys.readouterr().err
    assert not (tmp_path / "x.csv").exists()
    refused = [
        (["--time-offset", "nan", "-o", "x.mcap"], "--time-offset must be finite"),
        (["--time-offset", "3e9", "-o", "x.mcap"], "/joint_states: times must lie in [0, 2^31)"),
        (["--gps", "100", "0", "0", "-o", "x.mcap"], "latitude must lie in [-90, 90]"),
        (["--pose", "period=0.5", "-o", "x.mcap"], "--pose: a pose or GPS sensor's"),
        (["--pose-period", "0.5", "-o", "x.mcap"], "--pose: a pose or GPS sensor's"),
        (["--gyro", "arw=x", "-o", "x.mcap"], "--gyro arw=x: 'x' is not a number"),
        (["--gyro", "noise=1", "-o", "x.mcap"], "--gyro: unknown setting 'noise'"),
        (["--unsigned", "-o", "x.mcap"], "--unsigned describes a counter that rolls over"),
    ]
    for extra, message in refused:
        *options, _, name = extra
        assert main(["synth", *options, "-o", str(tmp_path / name)]) == 1
        assert message in capsys.readouterr().err
        assert not (tmp_path / name).exists()


def test_wrapped_headings_are_read_as_the_small_turns_they_are():
    """A trajectory with headings wrapped to (-pi, pi], as most tools write them: the jump
    across +-pi was read as a turn within one interval (a gyro rate of 62 rad/s where the
    truth peaks at 1.16, a wheel at 379 rad/s)."""
    t = np.arange(501) * 0.02
    unwrapped = dd.simulate(ROBOT, np.tile([6.0, 9.0], (500, 1)), times=t).poses
    wrapped = unwrapped.copy()
    wrapped[:, 2] = np.remainder(wrapped[:, 2] + np.pi, 2 * np.pi) - np.pi
    assert np.abs(np.diff(wrapped[:, 2])).max() > 6  # it does wrap
    for poses in (unwrapped, wrapped):
        gyro = sensors.gyro_readings(ROBOT, t, poses)
        encoders = sensors.encoder_readings(ROBOT, t, poses)
        np.testing.assert_allclose(gyro.rates, 3.0 * 0.05 / 0.3, rtol=1e-9)
        speeds = np.diff(encoders.run(0).wheels, axis=0) / 0.02
        np.testing.assert_allclose(speeds, np.tile([6.0, 9.0], (500, 1)), rtol=1e-9)


def test_an_ideal_gyro_integrates_back_to_the_turn_on_uneven_stamps():
    """Each sample the duration-weighted mean of its two intervals' rates: the gyro's angle
    (the rate linear between samples) ends on the trajectory's turn to rounding, and at each
    sample between is off by exactly the trapezoid's error where the rate steps, d[m-1] d[m]
    (w[m] - w[m-1]) / (2 (d[m-1] + d[m])), as the reading's comment states (it drifted
    2.2e-3 rad off before)."""
    rng = np.random.default_rng(0)
    t = np.concatenate([[0.0], np.cumsum(rng.uniform(0.005, 0.05, 600))])
    wheels = np.stack([6 + 4 * np.sin(0.7 * t[:-1]), 6 - 4 * np.cos(0.5 * t[:-1])], -1)
    path = dd.simulate(ROBOT, wheels, times=t)
    gyro = sensors.gyro_readings(ROBOT, t, path.poses)
    turned = path.poses[:, 2] - path.poses[0, 2]
    assert abs(gyro.angles[0, -1] - turned[-1]) < 1e-12
    d, w = np.diff(t), np.diff(path.poses[:, 2]) / np.diff(t)
    stated = d[:-1] * d[1:] * (w[1:] - w[:-1]) / (2 * (d[:-1] + d[1:]))
    np.testing.assert_allclose(gyro.angles[0, 1:-1] - turned[1:-1], stated, rtol=0, atol=1e-12)
    assert np.abs(gyro.angles[0] - turned).max() < 5e-4


@pytest.mark.parametrize("shift", [0.0, 2 * np.pi], ids=["(-pi, pi]", "[0, 2 pi)"])
def test_headings_wrapped_to_any_turn_are_read_as_unwrapped_ones(shift):
    """Headings stored in [0, 2 pi), as some tools write them, read as those in (-pi, pi]
    and the unwrapped ones: each sensor's readings the same (a [0, 2 pi) trajectory was read
    as unwrapped, its wrap as a turn of -2 pi: a gyro 314 rad/s off, wheels 19 rad off, a
    pose sensor's heading interpolated across the wrap)."""
    t = np.arange(501) * 0.02
    unwrapped = dd.simulate(ROBOT, np.tile([6.0, 9.0], (500, 1)), times=t).poses
    wrapped = unwrapped.copy()
    wrapped[:, 2] = np.remainder(wrapped[:, 2] + np.pi, 2 * np.pi) - np.pi
    wrapped[:, 2] = np.where(wrapped[:, 2] < 0, wrapped[:, 2] + shift, wrapped[:, 2])
    model = sensors.AbsoluteModel(period=0.05)  # between samples: interpolated
    read = [
        (
            sensors.gyro_readings(ROBOT, t, poses).rates,
            np.asarray(sensors.encoder_readings(ROBOT, t, poses).readings),
            sensors.absolute_readings(ROBOT, t, poses, model).poses,
        )
        for poses in (unwrapped, wrapped)
    ]
    np.testing.assert_allclose(read[1][0], read[0][0], rtol=0, atol=1e-9)
    np.testing.assert_allclose(read[1][1], read[0][1], rtol=0, atol=1e-9)
    headings = read[1][2][..., 2] - read[0][2][..., 2]
    np.testing.assert_allclose(dd.batch.wrap_angle(headings), 0.0, atol=1e-9)
    np.testing.assert_allclose(read[1][2][..., :2], read[0][2][..., :2], atol=1e-9)


# The compiled kernel against NumPy's stages, on a batch of different trajectories: every
# error source it takes, counters of each kind, wrapped and unwrapped headings.
KERNEL_MODELS = {
    "ideal, rad": sensors.EncoderModel(),
    "12-bit signed, biases, a slip": sensors.EncoderModel(
        ticks_per_revolution=4096, counter_bits=12, radius_bias=(0.01, -0.01), track_bias=0.02,
        slips=(sensors.Slip(1.0, 2.0, "left", 0.5),),
    ),
    "10-bit unsigned, noise, geometry spread": sensors.EncoderModel(
        ticks_per_revolution=1024, counter_bits=10, signed=False, wheel_noise=(1e-4, 3e-4),
        geometry_sigma=(0.01, 0.01, 0.02),
    ),
    "64-bit unsigned, noise, rad": sensors.EncoderModel(wheel_noise=2e-4),
    "64-bit unsigned counts": sensors.EncoderModel(
        ticks_per_revolution=2048, counter_bits=64, signed=False
    ),
}  # fmt: skip


@pytest.mark.skipif(
    importlib.util.find_spec("numba") is None, reason="numba (the fast extra) is not installed"
)
@pytest.mark.parametrize("model", KERNEL_MODELS.values(), ids=KERNEL_MODELS)
@pytest.mark.parametrize("headings", ["wrapped", "wrapped to [0, 2 pi)", "unwrapped", "shared"])
def test_the_compiled_encoders_read_what_numpys_stages_read(monkeypatch, model, headings):
    from diffdrive.sensors import encoders

    rng = np.random.default_rng(5)
    scale = rng.uniform(0.5, 1.5, (12, 1))
    wheels = np.stack([6 + 4 * np.sin(scale * T[:-1]), 6 - 4 * np.cos(0.5 * scale * T[:-1])], -1)
    poses = dd.simulate(SKID, wheels, times=T).poses  # (12, 501, 3): a skid steer's offset
    robots = None
    if headings == "wrapped":
        poses[..., 2] = dd.batch.wrap_angle(poses[..., 2])
    elif headings == "wrapped to [0, 2 pi)":
        poses[..., 2] = np.remainder(poses[..., 2], 2 * np.pi)
    elif headings == "unwrapped":
        poses[..., 2] += 8.0  # beyond pi: any turn's window reads alike
    else:  # one trajectory that every robot drives
        poses, robots = poses[3], 12
    fast = sensors.encoder_readings(SKID, T, poses, model, robots=robots, seed=7)
    monkeypatch.setattr(encoders, "_compiled", lambda: False)
    slow = sensors.encoder_readings(SKID, T, poses, model, robots=robots, seed=7)
    assert fast.readings.dtype == slow.readings.dtype
    if model.ticks_per_revolution is None:
        np.testing.assert_allclose(fast.readings, slow.readings, rtol=0, atol=1e-10)
    else:  # whole counts: the same, but for a sum a rounding away from a count's edge
        differ = fast.readings != slow.readings
        assert np.count_nonzero(differ) <= 2, np.argwhere(differ)
    np.testing.assert_array_equal(fast.slipping, slow.slipping)
    np.testing.assert_array_equal(fast.geometry, slow.geometry)


def test_the_compiled_encoders_refuse_what_numpy_refuses():
    poses = np.repeat(path().poses[None], 3, axis=0)
    poses[1, 7, 0] = np.nan
    with pytest.raises(ValueError, match="poses must be finite"):
        sensors.encoder_readings(ROBOT, T, poses)
    far = np.repeat(path().poses[None], 2, axis=0)
    far[..., :2] *= 1e16  # 10^18 counts and more: past an int64
    with pytest.raises(ValueError, match="more counts than an int64 holds"):
        sensors.encoder_readings(ROBOT, T, far, sensors.EncoderModel(ticks_per_revolution=4096))
