"""diffdrive.export and ``diffdrive export``: each target's file read back with a YAML parser
and checked against the structure its consumer expects, the figures against their stated
derivation, and calibrate-then-export from logs."""

import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import diffdrive as dd
from diffdrive import export, sensors
from diffdrive.calibration import noise
from diffdrive.cli import main
from diffdrive.estimation.settings import Encoders

yaml = pytest.importorskip("yaml")

NOMINAL = dd.DiffDrive(wheel_radius=0.05, track_width=0.3)
CALIBRATED = dd.DiffDrive(left_wheel_radius=0.0502, right_wheel_radius=0.0499, track_width=0.305)
MODEL = noise.NoiseModel.symmetric(1e-4, 0.002, 0.005, 0.001, 0.01)


# diff_drive_controller's documented parameters and their declared types
# (ros2_controllers, diff_drive_controller/src/diff_drive_controller_parameter.yaml).
DIFF_DRIVE_PARAMETERS = {
    "left_wheel_names": "string_array",
    "right_wheel_names": "string_array",
    "wheel_separation": "double",
    "wheels_per_side": "int",
    "wheel_radius": "double",
    "wheel_separation_multiplier": "double",
    "left_wheel_radius_multiplier": "double",
    "right_wheel_radius_multiplier": "double",
    "odom_frame_id": "string",
    "base_frame_id": "string",
    "pose_covariance_diagonal": "double_array",
    "twist_covariance_diagonal": "double_array",
    "open_loop": "bool",
    "position_feedback": "bool",
    "enable_odom_tf": "bool",
    "cmd_vel_timeout": "double",
    "publish_limited_velocity": "bool",
    "velocity_rolling_window_size": "int",
    "use_stamped_vel": "bool",
    "publish_rate": "double",
}
# Nav2 AMCL's parameters that the differential model's file sets, and their types.
AMCL_PARAMETERS = {
    "robot_model_type": "string",
    "alpha1": "double",
    "alpha2": "double",
    "alpha3": "double",
    "alpha4": "double",
    "update_min_d": "double",
    "update_min_a": "double",
}
ROS_TYPES = {
    "double": lambda v: type(v) is float,
    "int": lambda v: type(v) is int,
    "string": lambda v: type(v) is str,
    "bool": lambda v: type(v) is bool,
    "string_array": lambda v: isinstance(v, list) and all(type(x) is str for x in v),
    "double_array": lambda v: isinstance(v, list) and all(type(x) is float for x in v),
}
WHEELS = ("left_wheel_joint", "right_wheel_joint")
DRIVE = export.DriveConstants(1.1, 2.9, 0.4, 3.3, 0.6)


def c_members(struct: str) -> set[str]:
    """The member names of one of the C core's configuration structs, read from its header."""
    headers = Path(__file__).resolve().parents[1] / "c" / "include" / "diffdrive"
    text = "".join(path.read_text() for path in headers.glob("*.h"))
    body = re.search(r"typedef struct \{(.*?)\} " + struct + ";", text, re.S)
    assert body is not None, struct
    declarations = re.sub(r"/\*.*?\*/", "", body.group(1), flags=re.S)
    return set(re.findall(r"(\w+)(?:\[\d+\])?\s*[,;]", declarations))


def wpilib_schema():
    import json

    return json.loads(export.WPILIB_SCHEMA.read_text())


@pytest.mark.parametrize("target", export.TARGETS)
def test_each_file_has_the_structure_its_consumer_reads(target, tmp_path):
    """Each file read back as its consumer reads it: a ROS 2 parameter file with PyYAML, every
    parameter one the node documents and of its declared type (ros2 param load refuses a
    float for an int); WPILib's JSON against its schema."""
    path = tmp_path / f"{target}.file"
    options: dict[str, object] = {"wheel_names": WHEELS} if target == "ros2" else {}
    if target == "wpilib":
        options["drive"] = DRIVE
    if target == "c-header":
        options["encoders"] = Encoders(ticks_per_revolution=4096, counter_bits=16)
    figures = export.export(target, CALIBRATED, NOMINAL, MODEL, path, **options)
    if target == "c-header":  # compiled and run in test_c_core; here its fields are the C's
        text = path.read_text()
        for kind, name in (("odometry", "dd_odometry_config"), ("filter", "dd_filter_config")):
            fields = re.findall(r"\.(\w+) = ", text.split(f"diffdrive_{kind} = ")[1].split("};")[0])
            assert fields == list(figures[kind])
            assert set(fields) <= c_members(name), fields
        return
    if target == "wpilib":
        import json

        jsonschema = pytest.importorskip("jsonschema")
        document = json.loads(path.read_text())
        jsonschema.validate(document, wpilib_schema())
        assert document["trackWidth"] == pytest.approx(0.305)
        assert (document["kS"], document["kV"], document["kA"]) == (1.1, 2.9, 0.4)
        assert (document["kVAngular"], document["kAAngular"]) == (3.3, 0.6)
        assert len(document["stateStdDevs"]) == 3
        assert all(name in document["units"] for name in figures)
        return
    loaded = yaml.safe_load(path.read_text())
    ((node, body),) = loaded.items()
    assert node == export.NODES[target]
    assert list(body) == ["ros__parameters"]  # node_name: ros__parameters: ...
    parameters = body["ros__parameters"]
    assert list(parameters) == list(figures)
    for key, value in figures.items():
        if isinstance(value, str | int) or (isinstance(value, list) and isinstance(value[0], str)):
            assert parameters[key] == value
        else:  # floats written in full, read back exactly
            np.testing.assert_array_equal(parameters[key], value)
    declared = {"ros2": DIFF_DRIVE_PARAMETERS, "amcl": AMCL_PARAMETERS}.get(target)
    if declared is not None:
        for key, value in parameters.items():
            assert key in declared, f"{key} is no parameter of {node}"
            assert ROS_TYPES[declared[key]](value), (key, value, declared[key])
    if target == "ros2":
        assert parameters["left_wheel_names"] == ["left_wheel_joint"]
        assert parameters["velocity_rolling_window_size"] == 10
        assert parameters["wheel_separation"] == 0.3
        assert parameters["wheel_separation_multiplier"] == pytest.approx(0.305 / 0.3)
        assert parameters["left_wheel_radius_multiplier"] == pytest.approx(1.004)
        for key in ("pose_covariance_diagonal", "twist_covariance_diagonal"):
            assert len(parameters[key]) == 6
            assert all(v > 0 for v in parameters[key])
    elif target == "robot_localization":
        matrix = np.array(parameters["process_noise_covariance"]).reshape(15, 15)
        assert np.all(np.diag(matrix) > 0)
        assert np.count_nonzero(matrix - np.diag(np.diag(matrix))) == 0
    else:
        assert parameters["robot_model_type"] == "nav2_amcl::DifferentialMotionModel"
        assert all(parameters[f"alpha{i}"] > 0 for i in range(1, 5))
        assert (parameters["update_min_d"], parameters["update_min_a"]) == (0.25, 0.2)


@pytest.mark.parametrize(
    "model",
    [noise.NoiseModel.symmetric(0.0, 0.0, 0.01), noise.NoiseModel.symmetric(1e-4)],
    ids=["a track spread alone", "wheel noise alone"],
)
def test_every_exported_variance_is_one_a_consumer_can_invert(model):
    """No variance of the ROS parameters is 0 (a track spread alone leaves a straight line's
    pose and the sideways velocity exactly 0): each is at least the floor the bags carry,
    ``io.ros.covariance.FLOOR``, and the sideways velocity is that floor."""
    from diffdrive.io.ros.covariance import FLOOR

    at = export.Reference(distance=1.0, speed=0.5, rate=50.0)
    ros = export.parameters("ros2", NOMINAL, NOMINAL, model, at, wheel_names=WHEELS)
    for key in ("pose_covariance_diagonal", "twist_covariance_diagonal"):
        assert min(ros[key]) >= FLOOR, (key, ros[key])
    assert ros["twist_covariance_diagonal"][1] == FLOOR


def test_the_figures_follow_their_stated_derivation():
    """With the wheel noise alone: the pose diagonal is Odometry's covariance after 1 m
    straight; the twist's that of the mean of a 10-update window of per-update velocities
    (k v rate / (2 window), 2 k v rate / (window T^2)); WPILib's the square roots."""
    model = noise.NoiseModel.symmetric(1e-4, 0.0, 0.0, 0.0, 0.0)
    at = export.Reference(distance=1.0, speed=0.5, rate=50.0)
    ros = export.parameters("ros2", NOMINAL, NOMINAL, model, at, wheel_names=WHEELS)
    odometry = dd.Odometry(NOMINAL, wheel_noise=1e-4)
    odometry.update_arrays("increments", np.full(100, 0.2), np.full(100, 0.2))  # 1 m
    covariance = odometry.covariance
    assert ros["pose_covariance_diagonal"][0] == pytest.approx(covariance[0, 0], rel=1e-9)
    assert ros["pose_covariance_diagonal"][5] == pytest.approx(covariance[2, 2], rel=1e-9)
    assert ros["twist_covariance_diagonal"][0] == pytest.approx(1e-4 * 0.5 * 50 / 2 / 10)
    assert ros["twist_covariance_diagonal"][5] == pytest.approx(2e-4 * 0.5 * 50 / 0.09 / 10)
    wpilib = export.parameters("wpilib", NOMINAL, NOMINAL, model, at)
    np.testing.assert_allclose(wpilib["stateStdDevs"], np.sqrt(np.diag(covariance)), rtol=1e-9)
    assert "kS" not in wpilib  # no drive identification: no feedforward
    with pytest.raises(ValueError, match="target must be one of"):
        export.parameters("gazebo", NOMINAL, NOMINAL, model, at)
    with pytest.raises(ValueError, match="speed must be > 0"):
        export.Reference(speed=0.0)
    with pytest.raises(ValueError, match="needs left_wheel_names and right_wheel_names"):
        export.parameters("ros2", NOMINAL, NOMINAL, model, at)


def test_the_controllers_published_twist_has_the_variance_written():
    """diff_drive_controller's published velocity, simulated as its odometry.cpp computes it
    (each update's wheel travel over its period, the rolling mean of 10), with wheel noise of
    variance k |travel| per update: its variance is the file's twist diagonal."""
    k, v, rate, window = 1e-4, 0.5, 50.0, 10
    model = noise.NoiseModel.symmetric(k, 0.0, 0.0, 0.0, 0.0)
    at = export.Reference(speed=v, rate=rate, window=window)
    written = export.parameters("ros2", NOMINAL, NOMINAL, model, at, wheel_names=WHEELS)
    rng = np.random.default_rng(5)
    travel = v / rate
    wheels = travel + rng.standard_normal((40_000, window, 2)) * np.sqrt(k * travel)
    linear = (wheels.mean(axis=2) * rate).mean(axis=1)  # per update, then the window's mean
    angular = ((wheels[..., 1] - wheels[..., 0]) / NOMINAL.track_width * rate).mean(axis=1)
    assert np.var(linear) == pytest.approx(written["twist_covariance_diagonal"][0], rel=0.03)
    assert np.var(angular) == pytest.approx(written["twist_covariance_diagonal"][5], rel=0.03)


def angle_diff(a, b):
    """nav2_amcl's angleutils::angle_diff, as its header has it."""
    a, b = np.arctan2(np.sin(a), np.cos(a)), np.arctan2(np.sin(b), np.cos(b))
    d1 = a - b
    d2 = 2 * np.pi - abs(d1)
    if d1 > 0:
        d2 *= -1.0
    return d1 if abs(d1) < abs(d2) else d2


def _nav2_sampler(particles, old, new, alphas, rng):
    """One update of nav2_amcl::DifferentialMotionModel::odometryUpdate, as its source reads,
    over particles ``(P, 3)``: the odometry moved from ``old`` to ``new`` (odom frame)."""

    a1, a2, a3, a4 = alphas
    dx, dy = new[0] - old[0], new[1] - old[1]
    trans = np.hypot(dx, dy)
    rot1 = 0.0 if trans < 0.01 else angle_diff(np.arctan2(dy, dx), old[2])
    rot2 = angle_diff(angle_diff(new[2], old[2]), rot1)
    noise1 = min(abs(angle_diff(rot1, 0.0)), abs(angle_diff(rot1, np.pi)))
    noise2 = min(abs(angle_diff(rot2, 0.0)), abs(angle_diff(rot2, np.pi)))
    count = len(particles)
    rot1_hat = rot1 - rng.normal(0, np.sqrt(a1 * noise1**2 + a2 * trans**2), count)
    trans_hat = trans - rng.normal(0, np.sqrt(a3 * trans**2 + a4 * (noise1**2 + noise2**2)), count)
    rot2_hat = rot2 - rng.normal(0, np.sqrt(a1 * noise2**2 + a2 * trans**2), count)
    particles[:, 0] += trans_hat * np.cos(particles[:, 2] + rot1_hat)
    particles[:, 1] += trans_hat * np.sin(particles[:, 2] + rot1_hat)
    particles[:, 2] += rot1_hat + rot2_hat


def _amcl(odometry, alphas, at, rng, count=40_000):
    """AMCL's particles after the odometry ``(K, 3)`` seen at each scan, updated whenever it
    has moved more than update_min_d along x or y or turned more than update_min_a since the
    last update (AmclNode::shouldUpdateFilter), and the index of the last update: the motion
    after it waits for the next."""
    particles, last, applied = np.zeros((count, 3)), odometry[0], 0
    for k, pose in enumerate(odometry[1:], 1):
        turned = abs(angle_diff(pose[2], last[2]))
        moved = abs(pose[0] - last[0]) > at.update_min_d or abs(pose[1] - last[1]) > at.update_min_d
        if moved or turned > at.update_min_a:
            _nav2_sampler(particles, last, pose, alphas, rng)
            last, applied = pose, k
    return particles, applied


# Motions the alphas were not fitted on (they are: 1 m straight, a 1 rad turn in place, 2 m
# arcs of radius 1 and 2 m): (v m/s, omega rad/s, duration s) at the Reference's defaults.
HELD_OUT = {
    "1.5 m straight": (0.5, 0.0, 3.0),
    "1.5 rad turn in place": (0.0, 1.0, 1.5),
    "3 m arc of radius 1.5 m": (0.5, 0.5 / 1.5, 6.0),
    "2 m arc of radius 1 m": (0.5, 0.5, 4.0),
}
UNEQUAL = dd.DiffDrive(left_wheel_radius=0.05, right_wheel_radius=0.0525, track_width=0.3)


@pytest.mark.slow
@pytest.mark.parametrize("robot", [NOMINAL, UNEQUAL], ids=["equal radii", "unequal radii"])
@pytest.mark.parametrize("scan_rate", [5.0, 10.0, 100.0])
def test_amcl_alphas_give_the_models_covariance_through_nav2s_sampler(robot, scan_rate):
    """A Monte Carlo of Nav2's sampler with the exported alphas, updating as AMCL does at the
    update_min_d and update_min_a written beside them and the scan rate given, on motions the
    fit never saw: its covariance, at AMCL's last update of each, is the noise model's there
    within the fit's own largest miss and the Monte Carlo's 5 % (the turn's x and y as their
    sum: AMCL spreads each update's translation noise along the update's first heading, which
    no alpha can change). The fit on its three motions alone missed a 2 m arc of radius 1 m
    by 20 % at 10 Hz; forcing an update at each motion's end, it matched a sampler AMCL does
    not run; and its minimax let alpha3 or alpha4 fall to 0 at 5 and 100 Hz, AMCL then
    spreading no translation noise."""
    at = export.Reference(scan_rate=scan_rate)
    model = noise.NoiseModel.symmetric(1e-4, 0.002, 0.005, 0.0, 0.0)
    figures = export.parameters("amcl", robot, robot, model, at)
    alphas = [figures[f"alpha{i}"] for i in range(1, 5)]
    assert min(alphas) > 0.0
    fit = export.amcl_fit(robot, model, at)
    assert fit.worst < 0.15
    rng = np.random.default_rng(11)
    track = robot.track_width
    for name, (v, omega, duration) in HELD_OUT.items():
        scans = np.unique(np.append(np.arange(0.0, duration, 1.0 / scan_rate), duration))
        odometry = dd.batch.exp(np.tile([v, 0.0, omega], (len(scans), 1)), scans)
        particles, applied = _amcl(odometry, alphas, at, rng)
        sampled = np.diag(np.cov(particles.T))
        moved = scans[applied]
        left = (v - 0.5 * track * omega) * moved / robot.left_wheel_radius
        right = (v + 0.5 * track * omega) * moved / robot.right_wheel_radius
        increments = np.tile([left / 100, right / 100], (100, 1))
        wanted = np.diag(noise.covariances(robot, increments, np.zeros(3), model)[1][-1])
        if v == 0.0:
            sampled = np.array([sampled[:2].sum(), sampled[2]])
            wanted = np.array([wanted[:2].sum(), wanted[2]])
        np.testing.assert_allclose(sampled, wanted, rtol=fit.worst + 0.05, err_msg=name)
    # The fit's own linearisation of the sampler, against the sampler on its own motions.
    from diffdrive.export.amcl import reference_motions

    for motion, predicted in zip(reference_motions(robot, at), fit.sampler, strict=True):
        particles = np.zeros((40_000, 3))
        for before, after in zip(motion.poses[:-1], motion.poses[1:], strict=True):
            _nav2_sampler(particles, before, after, alphas, rng)
        sampled = np.diag(np.cov(particles.T))
        np.testing.assert_allclose(sampled, np.diag(predicted), rtol=0.1, err_msg=motion.name)


def test_the_alphas_fit_is_the_least_largest_miss_there_is_and_why_it_is_not_10_percent():
    """Why AMCL's alphas cannot reach 10 % at Nav2's defaults (0.25 m, 0.2 rad, 10 Hz).

    The fit's largest miss is the linear programme's optimum (scipy's linprog, an independent
    solver). On the issue's three motions alone (1 m straight, 1 rad turn, 2 m arc of radius
    1 m) it is still 13.5 %: the arc's 0.25 m updates collect less translation noise per metre
    than the straight's 0.30 m ones (AMCL's noise grows with the square of each update's
    length), which the wheels' model does not. AMCL's own spread even depends on the
    direction in the odom frame: a straight at 45 degrees updates every 0.40 m, not 0.30 m,
    and gets a third more heading variance per metre from the same alphas."""
    from scipy.optimize import linprog

    from diffdrive.export import amcl

    at = export.Reference()
    model = noise.NoiseModel.symmetric(1e-4, 0.002, 0.005, 0.0, 0.0)
    motions = amcl.reference_motions(NOMINAL, at)
    wanted = np.array(
        [export.targets._motion_covariance(NOMINAL, model, m.increments) for m in motions]
    )
    for chosen in (motions, motions[:3]):  # the fit's motions, then the three
        rows = []
        for motion, covariance in zip(chosen, wanted, strict=False):
            made = amcl._matched(amcl.sampler_terms(motion.poses), motion.spin)
            target = amcl._matched(covariance, motion.spin)
            rows += [made[:, i] / target[i] for i in range(len(target))]
        a = np.array(rows)
        ones = np.ones((len(a), 1))
        lp = linprog(  # least t with |a x - 1| <= t, x >= 0
            np.r_[np.zeros(4), 1.0],
            A_ub=np.r_[np.c_[a, -ones], np.c_[-a, -ones]],
            b_ub=np.r_[np.ones(len(a)), -np.ones(len(a))],
        )
        fit = amcl.match_alphas(list(chosen), wanted[: len(chosen)])
        assert fit.worst == pytest.approx(lp.x[-1], abs=1e-3)
        assert fit.worst > 0.13
    fit = amcl.match_alphas(motions, wanted)
    per_metre = []
    for heading in (0.0, np.pi / 4):
        scans = np.arange(0.0, 2.0 + 1e-9, 1.0 / at.scan_rate)
        poses = dd.batch.exp(np.tile([at.speed, 0.0, 0.0], (len(scans), 1)), scans)
        c, s = np.cos(heading), np.sin(heading)
        turned = np.c_[c * poses[:, 0] - s * poses[:, 1], s * poses[:, 0] + c * poses[:, 1]]
        turned = np.c_[turned, poses[:, 2] + heading]
        points = amcl.update_points(turned, at.update_min_d, at.update_min_a)
        covariance = np.tensordot(fit.alphas, amcl.sampler_terms(turned[points]), axes=1)
        per_metre.append(covariance[2, 2] / np.hypot(*turned[points[-1], :2]))
    assert per_metre[1] / per_metre[0] == pytest.approx(4 / 3, rel=0.01)


def test_an_alpha_the_fit_leaves_at_zero_is_refused_by_the_motion_it_misses():
    """A model whose spread along the wider arc is a thousandth of what the straight's
    heading noise gives there: the fit would write alpha2 = 0 (AMCL spreading no heading noise
    from translation); it refuses, naming the term it then misses most."""
    from diffdrive.export import amcl

    at = export.Reference()
    model = noise.NoiseModel.symmetric(1e-4, 0.002, 0.005, 0.0, 0.0)
    motions = amcl.reference_motions(NOMINAL, at)
    wanted = np.array(
        [export.targets._motion_covariance(NOMINAL, model, m.increments) for m in motions]
    )
    assert min(amcl.match_alphas(motions, wanted).alphas) > 0.0
    assert motions[-1].name == "2 m arc of radius 2 m"
    wanted[-1, 0, 0] *= 1e-3
    with pytest.raises(ValueError, match=r"alpha2 fit to 0: .* 1 m straight's y is off by 100%"):
        amcl.match_alphas(motions, wanted)


def test_runs_and_a_noise_model_by_hand_are_not_both_taken(tmp_path, capsys):
    robot = tmp_path / "robot.toml"
    robot.write_text("wheel_radius = 0.05\ntrack_width = 0.3\n")
    run = tmp_path / "run.csv"
    run.write_text("t,left_angle,right_angle,x,y,theta\n0,0,0,0,0,0\n1,1,1,0.05,0,0\n")
    output = tmp_path / "params.yaml"
    argv = ["export", "--to", "ros2", "--robot", str(robot), str(run), "--k", "1e-3"]
    assert main([*argv, "-o", str(output)]) == 1
    assert "--k: a noise model by hand, where the runs identify one" in capsys.readouterr().err
    assert not output.exists()


@pytest.mark.parametrize(
    ("terms", "message"),
    [
        ((0.0, 0.0, 0.0), "no wheel noise .k, radius_sigma and track_sigma all 0"),
        ((1e-4, -0.01, 0.0), "noise model radius_sigma must be >= 0, got -0.01"),
        ((float("nan"), 0.0, 0.0), "noise model k must be finite"),
    ],
)
def test_a_noise_model_that_would_write_zero_or_wrong_covariances_is_refused(
    terms, message, tmp_path
):
    path = tmp_path / "params.yaml"

    def write():
        model = noise.NoiseModel.symmetric(*terms, 0.0, 0.0)
        export.export("ros2", NOMINAL, NOMINAL, model, path)

    with pytest.raises(ValueError, match=message):
        write()
    assert not path.exists()


def test_calibrate_then_export_from_logs(tmp_path, monkeypatch, capsys):
    """Two logs with ground truth: calibrate writes the robot, export identifies the noise
    on the same logs, holds it to them and writes a ROS 2 file with non-zero covariances."""
    monkeypatch.chdir(tmp_path)
    t = np.arange(1001) * 0.02
    logs = []
    for n, turn in enumerate((2.0, -2.0, 1.0)):
        wheels = np.stack(
            [6 - turn + 2 * np.sin(0.4 * t[:-1]), 6 + turn - 2 * np.sin(0.4 * t[:-1])], -1
        )
        path = dd.simulate(NOMINAL, wheels, times=t)
        model = sensors.EncoderModel(wheel_noise=1e-4, radius_bias=(0.01, 0.0))
        readings = sensors.encoder_readings(NOMINAL, t, path.poses, model, seed=n)
        logs.append(str(sensors.write_table(tmp_path / f"log{n}.csv", readings)))
    (tmp_path / "nominal.toml").write_text("wheel_radius = 0.05\ntrack_width = 0.3\n")
    assert main(["calibrate", *logs, "--robot", "nominal.toml", "-o", "robot.toml", "-q"]) == 0
    calibrated = dd.io.read_robot(tmp_path / "robot.toml")
    exported = ["--robot", "robot.toml", "--nominal", "nominal.toml", "-o", "ros.yaml"]
    joints = ["--joints", "wheel_l", "wheel_r"]
    assert main(["export", "ros2", *exported, *logs]) == 1
    assert "give --joints LEFT RIGHT" in capsys.readouterr().err
    assert main(["export", "ros2", *exported, *joints, *logs]) == 0
    printed = capsys.readouterr().out
    assert "noise model identified on 3 runs; the reference's accuracy 1 mm and 0.1 deg" in printed
    assert "held to its runs (the reference's own noise added): " in printed
    text = (tmp_path / "ros.yaml").read_text()
    assert "# held to its runs" in text  # the figures that passed, in the file
    parameters = yaml.safe_load(text)["diff_drive_controller"]["ros__parameters"]
    assert all(v > 0 for v in parameters["pose_covariance_diagonal"])
    assert parameters["wheel_radius"] == 0.05
    assert (parameters["left_wheel_names"], parameters["right_wheel_names"]) == (
        ["wheel_l"],
        ["wheel_r"],
    )
    for side in ("left", "right"):
        multiplier = parameters[f"{side}_wheel_radius_multiplier"]
        assert multiplier == pytest.approx(calibrated[f"{side}_wheel_radius"] / 0.05)
    assert parameters["wheel_separation_multiplier"] == pytest.approx(
        calibrated["track_width"] / 0.3
    )
    assert main(["export", "--to", "amcl", "-o", "none.yaml"]) != 0
    assert "export needs a noise model" in capsys.readouterr().err
    assert not (tmp_path / "none.yaml").exists()
    # Without a robot, the built-in one's geometry would land in a controller's configuration.
    assert main(["export", "--to", "ros2", "--k", "0.01", "-o", "none.yaml"]) != 0
    assert "writes the robot's geometry" in capsys.readouterr().err
    assert not (tmp_path / "none.yaml").exists()


def test_refusals_name_the_figures_that_fail():
    from diffdrive.evaluation import Consistency

    wide = Consistency(np.ones(10), 0.9, 0.6, 0.97, 3, 10)
    narrow = Consistency(np.ones(10), 4.2, 0.2, 0.55, 3, 10)
    assert export.refusals(wide, MODEL) == []
    (reason,) = export.refusals(narrow, MODEL)
    assert "holds 55% of the runs' poses inside its 95 % ellipse (ANEES 4.2)" in reason
    stuck = replace(noise.NoiseModel.symmetric(0.0, 0.002, 0.005, 0.001, 0.01), terms=noise.TERMS)
    left, right = export.refusals(wide, stuck)
    assert "wheel noise k_left came out at its bound, 0 m" in left
    assert "wheel noise k_right came out at its bound, 0 m" in right
    unstuck = replace(stuck, wheel_noise=(1e-4, 0.0))
    assert export.refusals(wide, unstuck) == [right]


@pytest.mark.slow
def test_the_optiodom_recipe_exports_what_its_runs_hold(tmp_path, monkeypatch, capsys):
    """The README's calibrate-then-export on an OptiOdom experiment: with the reference's
    accuracy held at motion capture's, k is found (it was 0, the errors piled onto a 13.6 mm
    reference) and the model holds its runs; with the reference stated as that 13.6 mm and
    2.6 degrees, k goes to its bound again and the export is refused, writing nothing, unless
    --accept-inconsistent, which the file then says."""
    from data import data_folder

    monkeypatch.chdir(tmp_path)
    runs = sorted(
        str(p) for p in (data_folder("optiodom-diffdrive") / "free" / "030120210006").glob("*run*")
    )
    (tmp_path / "nominal.toml").write_text("wheel_radius = 0.042\ntrack_width = 0.2\n")
    assert main(["calibrate", *runs, "--robot", "nominal.toml", "-o", "robot.toml", "-q"]) == 0
    argv = ["export", "--to", "wpilib", "--robot", "robot.toml", *runs, "-o", "w.json"]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    inside = float(printed.split("): ")[1].split("% of")[0])
    assert inside >= 80.0
    k = float(printed.split("noise model: k ")[1].split()[0])
    assert k > 1e-5
    import json

    deviations = json.loads((tmp_path / "w.json").read_text())["stateStdDevs"]
    assert deviations[0] > 0.005  # 0.12 mm before
    assert deviations[2] > 0.01  # 0.066 degree before
    loose = ["--reference-noise", "0.0136", "0.0454"]
    assert main([*argv[:-1], "refused.json", *loose]) == 1
    assert re.search("k_(left|right) came out at its bound, 0 m", capsys.readouterr().err)
    assert not (tmp_path / "refused.json").exists()
    assert main([*argv[:-1], "accepted.json", *loose, "--accept-inconsistent", "-q"]) == 0
    assert "written though its wheel noise k" in capsys.readouterr().err
    notes = json.loads((tmp_path / "accepted.json").read_text())["notes"]
    assert any(note.startswith("WRITTEN THOUGH INCONSISTENT") for note in notes)


def test_wpilib_takes_the_drive_identify_found(tmp_path, monkeypatch, capsys):
    """A SysId-like voltage log through ``diffdrive identify`` (kS 1 V, kV 3 V s/m, kA 0.5
    V s^2/m of the wheels' surface speed), then ``export --to wpilib --drive``: WPILib's units
    in a JSON file its schema admits."""
    import json

    from sysid_log import write_sysid

    jsonschema = pytest.importorskip("jsonschema")
    monkeypatch.chdir(tmp_path)
    write_sysid(tmp_path / "sysid.csv", NOMINAL.left_wheel_radius)
    robot = ["--wheel-radius", "0.05", "--track-width", "0.3"]
    assert main(["identify", "sysid.csv", *robot, "-o", "drive.toml"]) == 0
    assert "linear: kS 0.99" in capsys.readouterr().out
    drive = dd.io.read_drive(tmp_path / "drive.toml")["feedforward"]
    assert drive["ks"] == pytest.approx(1.0, rel=0.03)
    assert drive["kv"] == pytest.approx(3.0, rel=0.03)
    assert drive["ka"] == pytest.approx(0.5, rel=0.05)
    argv = ["export", "--to", "wpilib", *robot, "--k", "1e-4", "--drive", "drive.toml"]
    assert main([*argv, "-o", "drivetrain.json", "-q"]) == 0
    document = json.loads((tmp_path / "drivetrain.json").read_text())
    jsonschema.validate(document, wpilib_schema())
    assert document["kV"] == drive["kv"]
    assert document["trackWidth"] == 0.3
    assert "V s/m" in document["units"]["kV"]
    with pytest.raises(SystemExit):  # amcl takes no drive
        main(["export", "amcl", *robot, "--k", "1e-4", "--drive", "drive.toml"])
    assert "unrecognized arguments: --drive" in capsys.readouterr().err
    assert main(["identify", "sysid.csv", "-o", "x.toml"]) == 1
    assert "give --robot FILE, or --wheel-radius and --track-width" in capsys.readouterr().err
