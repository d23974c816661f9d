"""diffdrive.export and ``diffdrive export``: each target's file read back with a YAML parser
and checked against the structure its consumer expects, the figures against their stated
derivation, and calibrate-then-export from logs."""

import numpy as np
import pytest

import diffdrive as dd
from diffdrive import export, noise, sensors
from diffdrive.cli import main

yaml = pytest.importorskip("yaml")

NOMINAL = dd.DiffDrive(wheel_radius=0.05, track_width=0.3)
CALIBRATED = dd.DiffDrive(left_wheel_radius=0.0502, right_wheel_radius=0.0499, track_width=0.305)
MODEL = noise.NoiseModel(1e-4, 0.002, 0.005, 0.001, 0.01, np.zeros((5, 5)), 10, noise.TERMS)


@pytest.mark.parametrize("target", export.TARGETS)
def test_each_file_has_the_structure_its_consumer_reads(target, tmp_path):
    path = tmp_path / f"{target}.yaml"
    figures = export.export(target, CALIBRATED, NOMINAL, MODEL, path)
    loaded = yaml.safe_load(path.read_text())
    if target == "wpilib":
        (node,) = loaded
        values = loaded[node]
        assert len(values["stateStdDevs"]) == 3
        assert all(v > 0 for v in values["stateStdDevs"])
        return
    ((node, body),) = loaded.items()
    assert list(body) == ["ros__parameters"]  # node_name: ros__parameters: ...
    parameters = body["ros__parameters"]
    assert list(parameters) == list(figures)
    for key, value in figures.items():
        if isinstance(value, str):
            assert parameters[key] == value
        else:  # floats written in full, read back exactly
            np.testing.assert_array_equal(parameters[key], value)
    if target == "ros2":
        assert node == "diff_drive_controller"
        assert parameters["wheel_separation"] == 0.3
        assert parameters["wheel_separation_multiplier"] == pytest.approx(0.305 / 0.3)
        assert parameters["left_wheel_radius_multiplier"] == pytest.approx(1.004)
        for key in ("pose_covariance_diagonal", "twist_covariance_diagonal"):
            assert len(parameters[key]) == 6
            assert all(isinstance(v, float) and v > 0 for v in parameters[key])
    elif target == "robot_localization":
        assert node == "ekf_filter_node"
        matrix = np.array(parameters["process_noise_covariance"]).reshape(15, 15)
        assert np.all(np.diag(matrix) > 0)
        assert np.count_nonzero(matrix - np.diag(np.diag(matrix))) == 0
    else:
        assert node == "amcl"
        assert parameters["robot_model_type"] == "nav2_amcl::DifferentialMotionModel"
        assert all(parameters[f"alpha{i}"] > 0 for i in range(1, 5))


def test_the_figures_follow_their_stated_derivation():
    """With the wheel noise alone: the pose diagonal is Odometry's covariance after 1 m
    straight, the twist's k v rate / 2 and 2 k v rate / T^2, WPILib's their square roots."""
    model = noise.NoiseModel(1e-4, 0.0, 0.0, 0.0, 0.0, np.zeros((5, 5)), 1, ("k",))
    at = export.Reference(distance=1.0, speed=0.5, rate=50.0)
    ros = export.parameters("ros2", NOMINAL, NOMINAL, model, at)
    odometry = dd.Odometry(NOMINAL, k_left=1e-4, k_right=1e-4)
    odometry.update_arrays("increments", np.full(100, 0.2), np.full(100, 0.2))  # 1 m
    covariance = odometry.covariance
    assert ros["pose_covariance_diagonal"][0] == pytest.approx(covariance[0, 0], rel=1e-9)
    assert ros["pose_covariance_diagonal"][5] == pytest.approx(covariance[2, 2], rel=1e-9)
    assert ros["twist_covariance_diagonal"][0] == pytest.approx(1e-4 * 0.5 * 50 / 2)
    assert ros["twist_covariance_diagonal"][5] == pytest.approx(2e-4 * 0.5 * 50 / 0.09)
    wpilib = export.parameters("wpilib", NOMINAL, NOMINAL, model, at)
    np.testing.assert_allclose(wpilib["stateStdDevs"], np.sqrt(np.diag(covariance)), rtol=1e-9)
    amcl = export.parameters("amcl", NOMINAL, NOMINAL, model, at)
    assert amcl["alpha3"] == pytest.approx(covariance[0, 0])  # per m^2 of a 1 m straight
    assert amcl["alpha1"] == pytest.approx(1e-4 * 1.0 / 0.3, rel=1e-6)  # k turn / T, per rad^2
    with pytest.raises(ValueError, match="target must be one of"):
        export.parameters("gazebo", NOMINAL, NOMINAL, model, at)
    with pytest.raises(ValueError, match="speed must be > 0"):
        export.Reference(speed=0.0)


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
        model = noise.NoiseModel(*terms, 0.0, 0.0, np.zeros((5, 5)), 0, noise.TERMS[:3])
        export.export("ros2", NOMINAL, NOMINAL, model, path)

    with pytest.raises(ValueError, match=message):
        write()
    assert not path.exists()


def test_calibrate_then_export_from_logs(tmp_path, monkeypatch, capsys):
    """Two logs with ground truth: calibrate writes the robot, export identifies the noise
    on the same logs and writes a ROS 2 file with non-zero covariances."""
    monkeypatch.chdir(tmp_path)
    t = np.arange(1001) * 0.02
    logs = []
    for n, turn in enumerate((2.0, -2.0, 1.0)):
        wheels = np.stack(
            [6 - turn + 2 * np.sin(0.4 * t[:-1]), 6 + turn - 2 * np.sin(0.4 * t[:-1])], -1
        )
        path = dd.simulate(NOMINAL, wheels, times=t)
        model = sensors.EncoderModel(k_left=1e-4, k_right=1e-4, radius_bias=(0.01, 0.0))
        readings = sensors.encoder_readings(NOMINAL, t, path.poses, model, seed=n)
        logs.append(str(sensors.write_table(tmp_path / f"log{n}.csv", readings)))
    (tmp_path / "nominal.toml").write_text("wheel_radius = 0.05\ntrack_width = 0.3\n")
    assert main(["calibrate", *logs, "--robot", "nominal.toml", "-o", "robot.toml", "-q"]) == 0
    calibrated = dd.io.read_robot(tmp_path / "robot.toml")
    exported = ["--robot", "robot.toml", "--nominal", "nominal.toml", "-o", "ros.yaml"]
    assert main(["export", "--to", "ros2", *exported, *logs]) == 0
    parameters = yaml.safe_load((tmp_path / "ros.yaml").read_text())["diff_drive_controller"]
    parameters = parameters["ros__parameters"]
    assert all(v > 0 for v in parameters["pose_covariance_diagonal"])
    assert parameters["wheel_radius"] == 0.05
    for side in ("left", "right"):
        multiplier = parameters[f"{side}_wheel_radius_multiplier"]
        assert multiplier == pytest.approx(calibrated[f"{side}_wheel_radius"] / 0.05)
    assert parameters["wheel_separation_multiplier"] == pytest.approx(
        calibrated["track_width"] / 0.3
    )
    assert "noise model (identified on 3 runs" in capsys.readouterr().out
    assert main(["export", "--to", "amcl", "-o", "none.yaml"]) != 0
    assert "export needs a noise model" in capsys.readouterr().err
    assert not (tmp_path / "none.yaml").exists()
    # Without a robot, the built-in one's geometry would land in a controller's configuration.
    assert main(["export", "--to", "ros2", "--k", "0.01", "-o", "none.yaml"]) != 0
    assert "writes the robot's geometry" in capsys.readouterr().err
    assert not (tmp_path / "none.yaml").exists()
