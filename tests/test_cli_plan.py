"""``diffdrive plan`` and ``diffdrive follow``: what they write is what they report."""

from __future__ import annotations

import numpy as np
import pytest

from diffdrive.cli import main
from diffdrive.io import read_table

ROBOT = "left_wheel_radius = 0.1\nright_wheel_radius = 0.1\ntrack_width = 0.6\n"
LIMITS = ["--max-velocity", "1", "--max-acceleration", "1", "--max-wheel-velocity", "12"]


@pytest.fixture
def files(tmp_path):
    (tmp_path / "wp.csv").write_text("x,y,theta\n0,0,0\n3,1,0.5\n5,3,1.5\n")
    (tmp_path / "robot.toml").write_text(ROBOT)
    return tmp_path


def test_plan_writes_rows_within_the_limits_it_reports(files, capsys) -> None:
    out = files / "plan.csv"
    args = [str(files / "wp.csv"), "--robot", str(files / "robot.toml"), *LIMITS]
    assert main(["plan", *args, "-o", str(out), "--plot", str(files / "p.png")]) == 0
    printed = capsys.readouterr().out
    assert "wheel_velocity: at most 100.0 % of its limit" in printed
    table = read_table(out, ["t", "x", "y", "theta", "v", "omega", "left", "right"])
    # Rows between states interpolate them: within the limit to 1e-4 (the report rounds).
    assert np.abs(np.column_stack([table["left"], table["right"]])).max() <= 12 * (1 + 1e-4)
    assert table["v"].max() <= 1 + 1e-9
    assert (files / "p.png").stat().st_size > 0


@pytest.mark.slow
def test_follow_reports_robot_zero_as_written(files, capsys) -> None:
    out = files / "follow.csv"
    args = [str(files / "wp.csv"), "--robot", str(files / "robot.toml"), *LIMITS]
    extra = ["--tracker", "ltv", "--delay", "0.1", "--lag", "0.1", "--predict"]
    assert main(["follow", *args, *extra, "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    table = read_table(out, ["t", "x", "y", "theta", "cross_track"])
    written = 1e3 * np.abs(table["cross_track"]).max()
    assert f"cross-track max {written:.1f} mm" in printed
    assert "delay margin beyond the known delay" in printed


def test_plan_refuses_without_a_robot_and_writes_nothing(files, capsys) -> None:
    out = files / "plan.csv"
    assert main(["plan", str(files / "wp.csv"), *LIMITS, "-o", str(out)]) == 1
    assert "plan needs the robot" in capsys.readouterr().err
    assert not out.exists()


def test_plan_names_the_file_of_a_bad_path(files, capsys) -> None:
    (files / "bad.csv").write_text("x,y\n0,0\n0,0\n1,1\n")
    args = [str(files / "bad.csv"), "--robot", str(files / "robot.toml"), *LIMITS]
    assert main(["plan", *args, "-o", str(files / "x.csv")]) == 1
    assert "bad.csv: waypoints 0 and 1 repeat" in capsys.readouterr().err
    assert not (files / "x.csv").exists()


@pytest.mark.parametrize(
    ("command", "extra", "message"),
    [
        ("plan", ["--dt", "100"], "dt 100 s exceeds the plan's"),
        (
            "follow",
            ["--seed", "-1", "--wheel-noise", "1e-4"],
            "seed must be a whole number from 0 or None, got -1",
        ),
        ("follow", ["--seed", "3"], "--seed draws the wheel noise: give --wheel-noise too"),
        ("follow", ["--predict"], "--predict predicts over the delay and lag"),
    ],
)
def test_a_sampling_or_seed_that_cannot_be_used_is_named(files, capsys, command, extra, message):
    args = [str(files / "wp.csv"), "--robot", str(files / "robot.toml"), *LIMITS, *extra]
    assert main([command, *args, "-o", str(files / "x.csv")]) == 1
    assert message in capsys.readouterr().err
    assert not (files / "x.csv").exists()


@pytest.mark.slow
def test_evaluate_against_the_plan_agrees_with_follow(files, capsys) -> None:
    args = [str(files / "wp.csv"), "--robot", str(files / "robot.toml"), *LIMITS]
    assert main(["plan", *args, "-o", str(files / "plan.csv"), "-q"]) == 0
    extra = ["--delay", "0.1", "--lag", "0.1", "-q"]
    assert main(["follow", *args, *extra, "-o", str(files / "follow.csv")]) == 0
    capsys.readouterr()
    assert main(["evaluate", str(files / "follow.csv"), "--plan", str(files / "plan.csv")]) == 0
    printed = dict(line.split() for line in capsys.readouterr().out.splitlines())
    written = read_table(files / "follow.csv", ["t", "cross_track"])
    # The plan's rows every 0.02 s hold the path to well under a millimetre.
    assert float(printed["max_cross_track_m"]) == pytest.approx(
        np.abs(written["cross_track"]).max(), abs=2e-4
    )
    assert (
        main(
            [
                "evaluate",
                str(files / "follow.csv"),
                "--plan",
                str(files / "plan.csv"),
                "--truth",
                "x",
            ]
        )
        == 1
    )
    assert "neither --truth" in capsys.readouterr().err
    against = ["evaluate", str(files / "follow.csv"), "--plan", str(files / "plan.csv")]
    assert main([*against, "--rpe", "2", "--interpolate"]) == 1
    assert "--interpolate, --rpe: evaluate --plan reads the plan" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("x;y;yaw\n0;0;0\n3;1;0.5\n", "column 'yaw' is not read"),
        (
            "x,y,theta\n0,0,0\n3,1,30\n5,3,90\n",
            "waypoint 2 has a heading of 90: headings are radians",
        ),
    ],
)
def test_plan_refuses_headings_it_would_misread(files, capsys, text, message) -> None:
    (files / "odd.csv").write_text(text)
    args = [str(files / "odd.csv"), "--robot", str(files / "robot.toml"), *LIMITS]
    assert main(["plan", *args, "-o", str(files / "x.csv")]) == 1
    assert message in capsys.readouterr().err
    assert not (files / "x.csv").exists()


def test_plan_with_a_jerk_limit_reports_what_its_rows_hold(files, capsys) -> None:
    out = files / "plan.csv"
    args = [str(files / "wp.csv"), "--robot", str(files / "robot.toml"), *LIMITS]
    assert main(["plan", *args, "--max-jerk", "3", "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    table = read_table(out, ["t", "v", "omega"])
    from diffdrive import DiffDrive
    from diffdrive.control import PathLimits, limit_ratios

    robot = DiffDrive(wheel_radius=0.1, track_width=0.6)
    twists = np.column_stack([table["v"], table["omega"]])
    ratio = limit_ratios(table["t"], twists, robot, PathLimits(max_velocity=1, max_jerk=3))
    assert f"jerk: at most {100 * ratio['jerk'].max():.1f} % of its limit" in printed
    assert ratio["jerk"].max() <= 1.0


def test_plan_takes_sysid_gains_per_metre(files, capsys) -> None:
    """--feedforward KS KV KA are SysId's (V, V s/m, V s^2/m): a robot of 3-inch wheels at kV 3.13
    V s/m reaches about 2.7 m/s under 10 V (per rad/s, kV 3.13 would hold it under 0.21 m/s),
    and the voltage SysId's model gives on the written rows stays within the limit."""
    (files / "wp.csv").write_text("x,y\n0,0\n12,0\n")
    (files / "robot.toml").write_text("wheel_radius = 0.0762\ntrack_width = 0.69\n")
    out = files / "plan.csv"
    gains = ["--feedforward", "1.34", "3.13", "0.926", "--max-voltage", "10"]
    args = [str(files / "wp.csv"), "--robot", str(files / "robot.toml"), *gains]
    assert (
        main(["plan", *args, "--max-velocity", "4", "--max-acceleration", "3", "-o", str(out)]) == 0
    )
    table = read_table(out, ["t", "x", "y", "theta", "v", "omega", "left", "right"])
    surface = table["left"] * 0.0762  # m/s
    acceleration = np.gradient(surface, table["t"])
    volts = 1.34 * np.sign(surface) + 3.13 * surface + 0.926 * acceleration
    assert table["v"].max() > 2.5
    assert volts.max() <= 10 * 1.02  # the gradient of the written rows: a little rounding
    capsys.readouterr()
    without_ka = [a for a in args if a != "0.926"]
    with pytest.raises(SystemExit):
        main(["plan", *without_ka, "--max-velocity", "4", "-o", str(out)])
    assert "--feedforward: expected 3 arguments" in capsys.readouterr().err
    # --ks, --kv, --ka, the spelling before 0.9: the same plan; one alone names the others.
    old = [str(files / "wp.csv"), "--robot", str(files / "robot.toml"), "--max-voltage", "10"]
    old += ["--ks", "1.34", "--kv", "3.13", "--ka", "0.926"]
    again = files / "again.csv"
    argv = ["plan", *old, "--max-velocity", "4", "--max-acceleration", "3", "-o", str(again)]
    assert main(argv) == 0
    assert again.read_text() == out.read_text() or np.allclose(
        read_table(again, ["t", "x"])["x"], table["x"]
    )
    assert '"--ks 1.34 --kv 3.13 --ka 0.926" is now "--feedforward' in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["plan", *old[:-2], "--max-velocity", "4", "-o", str(out)])
    assert "--ks, --kv without --ka" in capsys.readouterr().err


def test_follow_drives_the_response_of_a_drive_file_and_says_so(files, capsys) -> None:
    drive = files / "drive.toml"
    drive.write_text(
        "[response]\ndelay = 0.04\ntime_constant = 0.05\ngain = 0.95\nacceleration = 30.0\n"
    )
    args = [str(files / "wp.csv"), "--robot", str(files / "robot.toml"), *LIMITS]
    assert main(["follow", *args, "--drive", str(drive), "-o", str(files / "f.csv")]) == 0
    printed = capsys.readouterr().out
    assert "delay 0.04 s, drive" in printed
    assert "time constant 0.05 s, gain 0.95, acceleration limit 30 rad/s^2" in printed
    (files / "volts.toml").write_text("[feedforward]\nks = 0.2\nkv = 2.0\nka = 0.3\n")
    out = files / "g.csv"
    assert main(["follow", *args, "--drive", str(files / "volts.toml"), "-o", str(out)]) == 1
    assert "volts.toml: follow --drive needs its [response] section" in capsys.readouterr().err
    assert not out.exists()
    assert main(["follow", *args, "--drive", str(drive), "--lag", "0.1", "-o", str(out)]) == 1
    assert "leave --lag out" in capsys.readouterr().err


@pytest.mark.slow
def test_follow_takes_the_mppi_tracker_and_its_known_delay(files, capsys) -> None:
    args = [str(files / "wp.csv"), "--robot", str(files / "robot.toml"), *LIMITS]
    out = files / "mppi.csv"
    extra = ["--delay", "0.1", "--dt", "0.05", "--seed", "1"]
    assert main(["mppi", *args, *extra, "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "follow: mppi, delay 0.1 s" in printed
    assert "delay margin beyond the known delay" in printed
    table = read_table(out, ["t", "x", "y", "theta", "cross_track"])
    assert np.abs(table["cross_track"]).max() < 0.1
    # mppi rolls its samples out through the delay and lag itself: no --predict to give.
    with pytest.raises(SystemExit):
        main(["mppi", *args, "--predict", "--delay", "0.1"])
    assert "unrecognized arguments: --predict" in capsys.readouterr().err
    # follow --tracker mppi, the spelling before 0.9: the same run, and a note.
    old = files / "old.csv"
    assert main(["follow", *args, "--tracker", "mppi", *extra, "-o", str(old)]) == 0
    assert old.read_text() == out.read_text()
    assert '"follow" --tracker mppi is now "mppi"' in capsys.readouterr().err


def _map(folder) -> str:
    """A ROS map (map.yaml and its image) 8 m x 4 m with a 0.6 m block on the path."""
    from PIL import Image

    pixels = np.full((80, 160), 254, dtype=np.uint8)  # 5 cm cells, free
    pixels[:, :2] = pixels[:, -2:] = pixels[:2] = pixels[-2:] = 0  # walls
    pixels[32:44, 54:66] = 0  # rows from the top: y 1.8-2.4 m; x 2.7-3.3 m
    Image.fromarray(pixels).save(folder / "room.pgm")
    (folder / "room.yaml").write_text(
        "image: room.pgm\nresolution: 0.05\norigin: [-1.0, -2.0, 0.0]\nnegate: 0\n"
        "occupied_thresh: 0.65\nfree_thresh: 0.196\n"
    )
    return str(folder / "room.yaml")


@pytest.mark.slow
def test_follow_steers_mppi_around_a_ros_map_and_writes_nav2_parameters(files, capsys) -> None:
    """A straight plan through a block on the map: the robot goes around it, the report's
    closest approach is the written poses', and the Nav2 file reads back as YAML."""
    import yaml

    from diffdrive.control import read_map

    (files / "line.csv").write_text("x,y,theta\n0,0,0\n5,0,0\n")
    args = [str(files / "line.csv"), "--robot", str(files / "robot.toml"), *LIMITS]
    out, nav2 = files / "around.csv", files / "mppi.yaml"
    extra = ["--delay", "0.1", "--lag", "0.1", "--dt", "0.05", "--seed", "2"]
    where = ["--obstacles", _map(files), "0.35", "--nav2-mppi", str(nav2)]
    assert main(["mppi", *args, *extra, *where, "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    table = read_table(out, ["t", "x", "y", "theta"])
    gaps = read_map(files / "room.yaml").clearance_at(np.column_stack([table["x"], table["y"]]))
    assert gaps.min() > 0.35
    assert f"closest {1e3 * (gaps.min() - 0.35):.0f} mm beyond the footprint" in printed
    assert "touching at 0 of" in printed
    end = 1e3 * np.hypot(table["x"][-1] - 5.0, table["y"][-1])
    assert f"end: robot 0 {end:.1f} mm from the plan's last pose" in printed
    assert end < 50.0
    assert "stalled" not in printed
    parameters = yaml.safe_load(nav2.read_text())["controller_server"]["ros__parameters"]
    follow_path = parameters["FollowPath"]
    assert follow_path["plugin"] == "nav2_mppi_controller::MPPIController"
    assert follow_path["batch_size"] == 1024
    assert follow_path["time_steps"] == 32  # the horizon and the two steps in flight
    assert follow_path["vx_max"] == pytest.approx(1.0)  # the plan's max_velocity
    assert follow_path["wz_max"] == pytest.approx(2 * 0.1 * 12 / 0.6)
    assert follow_path["ObstaclesCritic"]["inflation_radius"] == pytest.approx(0.65)
    assert "ObstaclesCritic" in follow_path["critics"]
    assert "not carried over: temperature and cost weights" in nav2.read_text()


def test_mppi_refuses_a_bad_map_or_footprint_and_follow_has_no_map(files, capsys) -> None:
    args = [str(files / "wp.csv"), "--robot", str(files / "robot.toml"), *LIMITS]
    room = _map(files)
    out = files / "x.csv"
    with pytest.raises(SystemExit):
        main(["mppi", *args, "--obstacles", room, "-o", str(out)])
    assert "--obstacles: expected 2 arguments" in capsys.readouterr().err
    assert main(["mppi", *args, "--obstacles", room, "-0.3", "-o", str(out)]) == 1
    assert "the footprint is the robot's radius, m (finite, >= 0)" in capsys.readouterr().err
    for option in (["--obstacles", room, "0.3"], ["--nav2-mppi", str(files / "n.yaml")]):
        with pytest.raises(SystemExit):  # follow's trackers steer around nothing
            main(["follow", *args, *option, "-o", str(out)])
        assert "unrecognized arguments" in capsys.readouterr().err
    (files / "bad.yaml").write_text("image: room.pgm\nresolution: 0.05\n")
    argv = ["mppi", *args, "--obstacles", str(files / "bad.yaml"), "0.3"]
    assert main([*argv, "-o", str(out)]) == 1
    assert "bad.yaml: the map's origin is missing" in capsys.readouterr().err
    assert not out.exists()


def test_mppi_checks_nav2s_figures_before_the_run_and_q_skips_the_margin(tmp_path, capsys):
    """``--nav2-mppi`` without a wheel limit was refused after the whole run (27 minutes on a
    long plan, 89 % of it the delay-margin search, with its CSV written): it is refused
    first, nothing written; and -q leaves the margin's search out."""
    from unittest import mock

    waypoints = tmp_path / "w.csv"
    waypoints.write_text("x,y\n0,0\n1,0\n2,1\n")
    robot = ["--robot", "wheel_radius=0.05,track_width=0.3", "--max-velocity", "0.5"]
    out, nav2 = tmp_path / "m.csv", tmp_path / "n.yaml"
    argv = ["mppi", str(waypoints), *robot, "-o", str(out), "--nav2-mppi", str(nav2)]
    with mock.patch("diffdrive.cli.plan.follow") as run:
        assert main(argv) == 1
    assert not run.called
    assert "need a wheel limit" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["w.csv"]
    with mock.patch("diffdrive.cli.plan.delay_margin") as margin:
        argv = ["follow", str(waypoints), *robot, "-o", str(out), "-q"]
        assert main(argv) == 0
    assert not margin.called
    assert out.exists()
