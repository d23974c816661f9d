"""Pictures: the figure and the animation leave the user's matplotlib alone, draw what they
say, and show progress when asked."""

import numpy as np
import pytest

import diffdrive as dd

matplotlib = pytest.importorskip("matplotlib")
from diffdrive.plot import animate, plot_trajectory  # noqa: E402

ROBOT = dd.DiffDrive(wheel_radius=0.05, track_width=0.3)


def trajectory():
    return dd.simulate(ROBOT, np.tile([6.0, 9.0], (50, 1)), dt=0.05)


@pytest.mark.slow
def test_plotting_keeps_the_users_backend_and_opens_no_pyplot_figure(tmp_path):
    import sys

    matplotlib.use("svg")
    path = trajectory()
    plot_trajectory(ROBOT, path.times, path.poses, tmp_path / "a.png")
    animate(ROBOT, path.times, path.poses, tmp_path / "a.gif", frames=3)
    assert matplotlib.get_backend() == "svg"
    if "matplotlib.pyplot" in sys.modules:
        assert sys.modules["matplotlib.pyplot"].get_fignums() == []
    assert (tmp_path / "a.png").stat().st_size > 10_000


def test_the_animated_robot_has_no_line_from_a_corner_to_its_centre(tmp_path, monkeypatch):
    from matplotlib.lines import Line2D

    drawn = []
    original = Line2D.set_data

    def record(self, *args):
        x, y = args if len(args) == 2 else args[0]  # matplotlib also calls set_data((x, y))
        drawn.append((np.asarray(x, dtype=float), np.asarray(y, dtype=float)))
        return original(self, *args)

    monkeypatch.setattr(Line2D, "set_data", record)
    path = trajectory()
    animate(ROBOT, path.times, path.poses, tmp_path / "b.gif", frames=2)
    bodies = [(x, y) for x, y in drawn if len(x) == 8]  # the outline and its heading
    assert bodies
    for x, y in bodies:
        # box corners 0-4, a break, then centre to nose: no segment joins corner 4 to the centre
        assert np.isnan(x[5])
        assert np.isnan(y[5])


@pytest.mark.slow
def test_the_animation_shows_its_progress_when_asked(tmp_path, capsys):
    path = trajectory()
    animate(ROBOT, path.times, path.poses, tmp_path / "c.gif", frames=4, progress=True)
    assert "4/4" in capsys.readouterr().err


def test_a_trajectory_prints_as_a_short_summary():
    text = repr(trajectory())
    assert text.startswith("Trajectory(50 steps over [0, 2.5] s, method='exact'")
    assert len(text) < 300
    many = dd.simulate(ROBOT, np.ones((4, 3, 10, 2)), dt=0.1)
    assert "4x3 robots, 10 steps" in repr(many)
    assert "<(4, 3, 3) array>" in repr(many)


@pytest.mark.slow
def test_the_plot_says_which_robot_it_assumed_for_the_wheels(tmp_path, monkeypatch):
    """The wheel-velocity panel of a file's path was drawn with the built-in robot, silently,
    when no robot was given (the TurtleBot and Husky panels were wrong)."""
    import diffdrive.plot as plotting
    from diffdrive.cli import main

    made = []
    original = plotting._figure

    def recorded(**options):
        made.append(original(**options))
        return made[-1]

    monkeypatch.setattr(plotting, "_figure", recorded)
    path = tmp_path / "path.csv"
    assert main(["simulate", "-o", str(path), "-q"]) == 0
    assert main(["plot", str(path), "-o", str(tmp_path / "a.png"), "-q"]) == 0
    assert "assumed: give --robot" in made[-1].axes[2].get_title()
    argv = ["plot", str(path), "--wheel-radius", "0.042", "--track-width", "0.2"]
    assert main([*argv, "-o", str(tmp_path / "b.png"), "-q"]) == 0
    assert made[-1].axes[2].get_title() == ""


@pytest.mark.slow
def test_error_bands_count_what_they_draw_and_fixes_draw_x_and_y_alone(tmp_path):
    """Errors of 1 sigma everywhere but one 3-sigma heading: inside all three at all but that
    pose; against fixes without headings the heading is neither drawn nor counted."""
    from diffdrive.plot import plot_error_bands

    times = np.arange(10) * 0.1
    covariances = np.tile(np.diag([0.01, 0.04, 0.0025]), (10, 1, 1))
    estimate = np.zeros((10, 3))
    truth = np.tile([0.1, -0.2, 0.05], (10, 1))
    truth[4, 2] = 0.15  # three sigmas of heading
    share = plot_error_bands(times, estimate, covariances, truth, tmp_path / "pose.png")
    assert share == pytest.approx(0.9)
    truth[:, 2] = np.nan
    share = plot_error_bands(times, estimate, covariances, truth, tmp_path / "xy.png", "GPS")
    assert share == 1.0
    assert (tmp_path / "xy.png").stat().st_size > 10_000
