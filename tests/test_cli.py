"""The command line: the main job in-process and as a real subprocess."""

import subprocess
import sys

import pytest

from diffdrive.cli import kinematics_report, main
from diffdrive.examples import example_robot


def test_main_job_prints_the_example_robot(capsys):
    assert main([]) == 0
    out = capsys.readouterr().out
    assert "track_width=0.2" in out
    assert "spin in place" in out


def test_report_rows_follow_the_model():
    robot = example_robot()
    report = kinematics_report(robot)
    # straight: 10 rad/s on 42 mm wheels is 0.42 m/s and an infinite radius.
    straight = next(line for line in report.splitlines() if line.startswith("straight"))
    assert "0.4200" in straight
    assert "inf" in straight


def test_unknown_option_is_a_usage_error():
    with pytest.raises(SystemExit) as exit_info:
        main(["--no-such-option"])
    assert exit_info.value.code == 2


def test_runs_as_a_subprocess():
    result = subprocess.run(
        [sys.executable, "-m", "diffdrive"], capture_output=True, text=True, check=True
    )
    assert "Modern Robotics" in result.stdout
    assert result.stderr == ""


def test_simulation_report_lists_each_method_with_the_same_distance():
    from diffdrive.cli import simulation_report

    rows = simulation_report(example_robot(), steps=400).splitlines()[2:]
    assert [row.split()[0] for row in rows] == ["euler", "rk2", "exact"]
    distances = {row.split()[-1] for row in rows}
    assert len(distances) == 1  # the distance does not depend on the heading
