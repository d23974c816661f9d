"""The README's Python tour runs as written."""

import re
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"


@pytest.mark.slow
def test_readme_python_blocks_run():
    from data import data_folder

    blocks = re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)
    assert blocks, "the README has no python example"
    for block in blocks:
        for folder in re.findall(r"shared/data/([\w-]+)", block):
            data_folder(folder)  # a block on the recordings: fail in CI, skip without them
        exec(compile(block, str(README), "exec"), {})


def test_readme_starts_with_the_two_setup_commands():
    text = README.read_text()
    commands = re.findall(r"```sh\n(.*?)```", text, flags=re.S)[0].strip().splitlines()
    assert [line.split("#")[0].strip() for line in commands] == ["make demo", "make test"]


@pytest.mark.slow
def test_the_command_line_walkthrough_makes_the_pictures_shown(tmp_path):
    """Runs the README's command-line block as written, then compares the figure it drew."""
    import shlex
    import subprocess
    import sys

    import matplotlib.image

    section = README.read_text().split("## Command line", 1)[1]
    block = re.search(r"```sh\n(.*?)```", section, flags=re.S).group(1)
    (tmp_path / "docs" / "figures").mkdir(parents=True)
    commands = [line.split("#")[0].strip() for line in block.splitlines()]
    for command in filter(None, commands):
        words = shlex.split(command)
        assert words[0] == ".venv/bin/diffdrive", command
        result = subprocess.run(
            [sys.executable, "-m", "diffdrive", *words[1:]],
            capture_output=True,
            text=True,
            cwd=tmp_path,
        )
        assert result.returncode == 0, (command, result.stderr)
    figure = "docs/figures/trajectory.png"
    assert figure in README.read_text()
    made = matplotlib.image.imread(tmp_path / figure)
    shown = matplotlib.image.imread(README.parent / figure)
    assert made.shape == shown.shape
    assert abs(float(made.mean()) - float(shown.mean())) < 1e-3
    assert (tmp_path / "trajectory.gif").stat().st_size > 10_000
    assert (tmp_path / "trajectory.tum").read_text().startswith("# t x y z qx qy qz qw")


def test_the_readme_has_each_section_once_and_speaks_to_users():
    text = README.read_text()
    for heading in ("## Command line", "## Odometry", "## Performance"):
        assert text.count(heading + "\n") == 1, heading
    for internal in ("seed 000's main job", "Issue ", "issue "):
        assert internal not in text, internal
    assert "a C compiler" in text.split("```sh", 1)[0]


def test_every_link_inside_the_readme_lands_on_a_heading():
    text = re.sub(r"```.*?```", "", README.read_text(), flags=re.S)  # a code comment is no heading
    # GitHub's anchors: the heading in lower case, punctuation but hyphens dropped, spaces
    # to hyphens.
    headings = re.findall(r"^#+ (.+)$", text, flags=re.M)
    anchors = {re.sub(r"[^\w\- ]", "", h.lower()).replace(" ", "-") for h in headings}
    links = re.findall(r"\]\(#([^)]+)\)", text)
    assert links, "the README links none of its sections"
    assert sorted(set(links) - anchors) == []


@pytest.mark.slow
def test_the_bag_walkthrough_runs_as_written(tmp_path, monkeypatch, capsys):
    import shlex

    from data import data_folder
    from diffdrive.cli import main

    section = README.read_text().split("## Robot logs", 1)[1]
    block = re.search(r"```sh\n(.*?)```", section, flags=re.S).group(1).replace("\\\n", " ")
    monkeypatch.chdir(tmp_path)
    bags = str(data_folder("ros-bags"))
    commands = [line.split("#")[0].strip() for line in block.splitlines()]
    printed: dict[str, str] = {}
    for command in filter(None, commands):
        if command.startswith("B="):
            continue
        words = shlex.split(command.replace("$B", bags))
        assert words[0] == ".venv/bin/diffdrive", command
        assert main(words[1:]) == 0, (command, capsys.readouterr().err)
        printed[words[1]] = printed.get(words[1], "") + capsys.readouterr().out
    assert (tmp_path / "tb3.mcap").stat().st_size > 100_000
    # What the text says the commands print (3.9 m calibrated, from /odom's first pose).
    assert "position error max 3.94" in printed["odometry"]
    assert "max_position_error_m                   3.94" in printed["evaluate"]


@pytest.mark.slow
def test_the_calibration_from_driving_runs_as_written(tmp_path, monkeypatch, capsys):
    """The block of "Calibration from ordinary driving", with the robot file its text gives:
    it writes the robot, with the distance scale the section quotes."""
    import shlex

    from data import data_folder
    from diffdrive.cli import main
    from diffdrive.io import read_robot

    section = README.read_text().split("## Calibration from ordinary driving", 1)[1]
    block = re.search(r"```sh\n(.*?)```", section, flags=re.S).group(1).replace("\\\n", " ")
    monkeypatch.chdir(tmp_path)
    (tmp_path / "husky.toml").write_text("wheel_radius = 0.165\ntrack_width = 0.555\n")
    bag = str(data_folder("ros-bags") / "husky_robot_localization_test1.bag")
    for command in filter(None, (line.strip() for line in block.splitlines())):
        if command.startswith("H="):
            continue
        words = shlex.split(command.replace("$H", bag))
        assert words[0] == ".venv/bin/diffdrive", command
        assert main(words[1:]) == 0, (command, capsys.readouterr().err)
    robot = read_robot(tmp_path / "robot.toml")
    assert 0.96 <= (robot["left_wheel_radius"] + robot["right_wheel_radius"]) / 0.33 <= 0.98
