"""The example scripts run and draw what the guides show (docs/guides/)."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

import docs_pages
from records import assert_as_recorded

ROOT = Path(__file__).resolve().parents[1]


def load(name: str):
    spec = importlib.util.spec_from_file_location(name, ROOT / "examples" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.slow
def test_step_size_error_shows_the_orders_and_exact_on_held_commands(tmp_path, capsys):
    script = load("step_size_error")
    output = tmp_path / "figure.png"
    script.main(["--output", str(output)])
    printed = capsys.readouterr().out
    assert f"figure: {output}" in printed
    assert_as_recorded("step_size_error", printed)
    import matplotlib.image

    pixels = matplotlib.image.imread(output)
    assert pixels.shape[:2] == (400, 1000)
    assert pixels[..., :3].std() > 0.05  # drawn on, not blank
    smooth, held = script.errors("smooth"), script.errors("held")
    # Ten times the steps: euler's error ten times smaller, rk2's and exact's a hundred.
    for method, factor in [("euler", 10), ("rk2", 100), ("exact", 100)]:
        ratio = smooth[method][3] / smooth[method][6]  # 100 steps against 1000
        assert np.isclose(ratio, factor, rtol=0.05), (method, ratio)
    assert max(held["exact"]) < script.ROUNDING
    assert min(held["rk2"]) > 1e-9
    # The guides quote the 1 ms figures (10,000 steps over the 10 s manoeuvre).
    readme = docs_pages.text()
    euler, rk2, exact = (
        f"{smooth[m][-1]:.1e}".replace("e-0", "e-") for m in ("euler", "rk2", "exact")
    )
    assert f"{euler} m, {rk2} m and {exact} m at 1 ms steps" in " ".join(readme.split())


@pytest.mark.slow
def test_commanded_path_draws_both_paths_within_the_wheel_limit(tmp_path, capsys):
    script = load("commanded_path")
    output = tmp_path / "paths.png"
    script.main(["--output", str(output)])
    printed = capsys.readouterr().out
    assert "largest wheel velocity 20.00 rad/s (limit 20.0)" in printed
    assert_as_recorded("commanded_path", printed)
    import matplotlib.image

    pixels = matplotlib.image.imread(output)
    assert pixels.shape[:2] == (450, 1100)
    assert pixels[..., :3].std() > 0.05
    commanded, limited = script.paths()
    assert np.abs(limited.wheel_velocities).max() <= script.MAX_WHEEL_VELOCITY
    assert np.abs(commanded.wheel_velocities).max() > script.MAX_WHEEL_VELOCITY
    np.testing.assert_allclose(limited.wheel_velocities[-1], [0.0, 0.0])  # the timeout


@pytest.mark.slow
def test_optiodom_calibration_table_and_figure_on_two_experiments(tmp_path):
    from data import data_folder

    script = load("optiodom_calibration")
    experiments, authors = script.load(data_folder("optiodom-diffdrive"))
    assert len(experiments) == 10
    two = {name: experiments[name] for name in ("ivanjko/231220200104", "circular/250620202345")}
    ours = script.results(two)
    table = script.markdown(ours, authors)
    assert table.count("\n") == 4  # header, rule, two experiments, the mean
    for name, row in ours.items():
        assert row["minimax"] <= authors[name]["OptiOdom"]
        assert row["least_squares"] < row["nominal"]
    held = script.held_out(two)
    assert held["ivanjko/231220200104"]["least_squares, held out"] == "refused"
    assert held["circular/250620202345"]["with offsets, held out"] == "refused"
    rows = script.held_out_markdown(held, authors)
    assert "| ivanjko/231220200104 | 3 | 11.5 |" in rows
    # Held out one run at a time, an experiment's row needs no other experiment: the two
    # rows are the record's (the whole table takes a minute).
    assert_as_recorded("optiodom_calibration", rows, only=lambda line: line.startswith("| "))
    script.draw(experiments[script.DRAWN], tmp_path / "figure.png")
    import matplotlib.image

    assert matplotlib.image.imread(tmp_path / "figure.png").shape[:2] == (600, 700)


@pytest.mark.slow
def test_ros_bags_example_calibrates_the_turtlebot3_and_aligns_the_husky_to_gps(tmp_path, capsys):
    from data import data_folder

    script = load("ros_bags")
    output = tmp_path / "bags.png"
    script.main(["--bags", str(data_folder("ros-bags")), "--output", str(output)])
    printed = capsys.readouterr().out
    assert "TurtleBot3: calibrated radii 0.0325" in printed
    assert "track 0.29" in printed
    assert "Husky: 359 m of wheel odometry against 989 GPS fixes" in printed
    assert_as_recorded("ros_bags", printed)
    import matplotlib.image

    assert matplotlib.image.imread(output)[..., :3].std() > 0.05
    readme = docs_pages.text()
    line = next(row for row in printed.splitlines() if row.startswith("Husky"))
    assert line.split("ATE ")[1] in " ".join(readme.split())  # the guides quote the figures


@pytest.mark.slow
def test_gyro_slip_example_fuses_better_on_the_synthetic_run(tmp_path, capsys):
    from data import data_folder

    script = load("gyro_slip")
    output = tmp_path / "gyro.png"
    script.main(["--bags", str(data_folder("ros-bags")), "--output", str(output)])
    printed = capsys.readouterr().out
    assert_as_recorded("gyro_slip", printed)
    readme = docs_pages.text(flat=True)
    lines = printed.splitlines()
    errors = {line.split()[0]: float(line.split()[1]) for line in lines[1:4]}
    assert errors["fused"] < errors["gyro"] < errors["wheels"]
    for heading, error in errors.items():
        assert f"{error:.2f} m" in readme, heading
    husky = next(line for line in lines if line.startswith("Husky"))
    for part in husky.split(": ", 1)[1].split(", "):
        assert part.split()[1] + " m" in readme


@pytest.mark.slow
def test_online_calibration_example_settles_near_batch_least_squares(tmp_path, capsys):
    from data import data_folder

    script = load("online_calibration")
    script.main(
        ["--data", str(data_folder("optiodom-diffdrive")), "--output", str(tmp_path / "online.png")]
    )
    printed = capsys.readouterr().out
    assert_as_recorded("online_calibration", printed)
    printed = printed.split("window 1:")[0]  # the default window's reports
    readme = docs_pages.text(flat=True)
    lines = [row for row in printed.splitlines() if "whole-path least squares" in row]
    assert len(lines) == 3  # two circular experiments and the free path
    for line in lines:
        differences = [float(part.strip(" %")) for part in line.split(": ")[1].split(",")]
        assert max(abs(d) for d in differences) < 1.0
        assert ", ".join(f"{d:+.2f} %" for d in differences) in readme


@pytest.mark.slow
def test_late_vision_example_fuses_the_camera_and_draws(tmp_path, capsys):
    script = load("late_vision")
    output = tmp_path / "late.png"
    script.main(["--output", str(output)])
    printed = capsys.readouterr().out
    assert_as_recorded("late_vision", printed)
    lines = printed.splitlines()
    alone, fused = (float(line.split("error ")[1].split()[0]) for line in lines[:2])
    assert fused < alone
    assert output.stat().st_size > 10_000


@pytest.mark.slow
def test_husky_fusion_example_prints_the_figures_the_readme_quotes(capsys, tmp_path):
    """Every figure the Husky example prints is the guides', and its GPS gaps meet the
    targets with no setting given: the smoother at most 2 % worse than interpolating the used
    fixes and at most 10 % worse than the dead reckoning through them at every gap, none
    refused, and at 10, 20 and 50 s within 0.59, 1.09 and 2.00 m of the fixes left out."""
    from data import data_folder

    script = load("husky_fusion")
    figure = tmp_path / "husky.png"
    script.main(["--bags", str(data_folder("ros-bags")), "--figure", str(figure)])
    printed = capsys.readouterr().out.replace(f"figure: {figure}", "")
    assert_as_recorded("husky_fusion", printed)
    readme = docs_pages.text(flat=True)
    tokens = [part.rstrip(":,") for part in printed.replace(";", " ").split()]
    figures = [n for n in tokens if n[:1].isdigit() and "." in n and not n.endswith(")")]
    assert len(figures) >= 40
    for number in figures:
        assert number in readme, number
    honest = next(line for line in printed.splitlines() if "covariance against GPS" in line)
    inside = honest.split("% inside the 95")[0].split()[-1]
    assert f"{inside} % inside the 95 % ellipse" in readme
    assert figure.stat().st_size > 10_000
    rows = [line for line in printed.splitlines() if " used, 0 refused): " in line]
    assert len(rows) == 6  # every gap, no fix refused
    bounds = {"10": 0.59, "20": 1.09, "50": 2.00}
    for row in rows:
        gap = row.split()[0]
        smoothed, interpolated, residuals = (
            float(part.split()[0]) for part in row.split(": ")[1].split(" | ")[:3]
        )
        assert smoothed <= 1.02 * interpolated, row
        assert smoothed <= 1.1 * residuals, row
        assert smoothed <= bounds.get(gap, np.inf), row


@pytest.mark.slow
def test_noise_model_example_prints_the_held_out_figures_the_readme_quotes(capsys, tmp_path):
    """The OptiOdom targets: held out by experiment, not overconfident (coverage >= 0.80,
    ANEES <= 3) on 9 of 10, pooled 93-98 % inside the 95 % ellipse with ANEES in [0.5, 1.5],
    passing on >= 90 % of the references the models draw themselves; by session on >= 8 of
    10. Every figure as the guides quote it."""
    from data import data_folder

    script = load("noise_model")
    folders = ["--data", str(data_folder("optiodom-diffdrive"))]
    figure = tmp_path / "bands.png"
    script.main([*folders, "--bags", str(data_folder("ros-bags")), "--figure", str(figure)])
    assert figure.stat().st_size > 10_000
    printed = capsys.readouterr().out
    assert_as_recorded("noise_model", printed)
    readme = docs_pages.text(flat=True)
    least = {"by experiment": 9, "by session": 8}
    for way, fewest in least.items():
        counted = next(line for line in printed.splitlines() if line.startswith(f"{way}: "))
        passed = int(counted.split(" on ")[1].split()[0])
        assert passed >= fewest, counted
        pooled = next(line for line in printed.splitlines() if line.startswith(f"{way}, pooled"))
        inside = float(pooled.split(": ")[1].split("%")[0])
        anees = float(pooled.split("ANEES ")[1])
        assert 93.0 <= inside <= 98.0, pooled
        assert 0.5 <= anees <= 1.5, pooled
        drawn = next(line for line in printed.splitlines() if line.startswith(f"{way}, on"))
        own = int(drawn.split(": ")[1].split("%")[0])
        assert own >= 90, drawn
        quoted = f"{way}: {passed} of 10, {inside:.1f} % and ANEES {anees:.2f} pooled, {own} %"
        assert quoted in readme, quoted
    turtle = next(line for line in printed.splitlines() if line.startswith("TurtleBot3"))
    share = turtle.split("% inside")[0].split()[-1]
    assert f"95 % ellipse at {share} % of poses" in readme
    assert "ANEES " + turtle.split("ANEES ")[1] in readme


@pytest.mark.slow
def test_follow_path_plans_within_the_limits_and_draws(tmp_path, capsys):
    script = load("follow_path")
    output = tmp_path / "follow.png"
    script.main(["--output", str(output)])
    printed = capsys.readouterr().out
    assert "voltage: at most" in printed
    assert_as_recorded("follow_path", printed)
    assert f"figure: {output}" in printed
    planned, followed = script.run()
    from diffdrive.control import limit_ratios

    for ratio in limit_ratios(planned.times, planned.twists, script.ROBOT, script.LIMITS).values():
        assert ratio.max() <= 1 + 1e-9
    assert followed.poses.shape[0] == script.ROBOTS


def test_no_example_draws_over_the_tracked_figures_by_default():
    """Run with no arguments, an example wrote docs/figures/*.png, which git tracks: its
    default is out/figures/ now, and --output docs/figures/NAME.png redraws the site's."""
    folder = Path(__file__).resolve().parents[1] / "examples"
    for script in sorted(folder.glob("*.py")):
        text = script.read_text()
        assert 'default=Path("docs' not in text, script.name
        assert '"docs" / "figures"' not in text, script.name


@pytest.mark.slow
def test_mppi_obstacles_goes_around_and_draws(tmp_path, capsys):
    """The guide's figure and its numbers: no touch, the closest approach and the time to
    the goal as printed."""
    script = load("mppi_obstacles")
    output = tmp_path / "mppi.png"
    script.main(["--output", str(output)])
    printed = capsys.readouterr().out
    assert "touched no" in printed
    assert_as_recorded("mppi_obstacles", printed)
    course, _, _, result, recording = script.run(7)
    poses = result.poses[0]
    closest = course.clearance(poses[:, :2]).min() - script.FOOTPRINT
    assert closest > 0.0
    assert f"closest {1e3 * closest:.0f} mm beyond the footprint" in printed
    assert len(recording.samples) == len(script.MOMENTS)
    assert recording.samples[0][1].shape == (48, 30, 2)
    readme = docs_pages.text()
    assert printed.split("goal reached in ")[1].split(" x the")[0].split(", ")[1] in readme


@pytest.mark.slow
def test_calibration_from_driving_meets_the_husky_targets_the_guide_quotes(capsys):
    """The Husky's wheels, GPS and gyro: the distance scale in 0.96-0.98, the gyro's clock
    about 0.1 s with its standard error, and the gyro-heading ATE of the nominal robot with
    the estimator's settings from the calibration in one call (``estimator_settings``) at most
    2.62 m; each figure as the calibration guide quotes it."""
    from data import data_folder

    script = load("calibrate_from_driving")
    script.main(["--bags", str(data_folder("ros-bags"))])
    printed = capsys.readouterr().out
    assert_as_recorded("calibrate_from_driving", printed)
    readme = docs_pages.text(flat=True)
    scale = next(line for line in printed.splitlines() if line.startswith("the estimator's"))
    assert 0.96 <= float(scale.split("distance scale ")[1].split()[0]) <= 0.98
    assert 0.05 <= float(scale.split("gyro clock ")[1].split()[0]) <= 0.15
    clock = next(line for line in printed.splitlines() if line.startswith("gyro clock"))
    value, error = float(clock.split()[5]), float(clock.split()[7])
    assert 0.05 <= value <= 0.15
    assert 0 < error < 0.05
    ate = next(line for line in printed.splitlines() if line.startswith("gyro-heading ATE"))
    figures = [float(part.split(" m")[0].split()[-1]) for part in ate.split(", ")]
    assert figures[2] <= 2.62 < figures[0]
    for quoted in (scale, clock, ate):
        assert quoted in readme, quoted


@pytest.mark.slow
def test_standin_camera_finds_the_camera_noise_and_the_guide_quotes_its_line(capsys):
    """OptiOdom's motion capture thinned to 2 Hz with 1 cm and 0.5 degree of noise: on the
    six runs of square/230620202042 the camera's noise is found within 6 % of its 1 cm, the
    delay within 3 of its standard errors of the 50 ms added, the held-out folds scored; the
    line's figures as the calibration guide's table quotes them."""
    import re

    from data import data_folder

    script = load("standin_camera")
    only = ["230620202042"]
    found = script.main(["--data", str(data_folder("optiodom-diffdrive")), "--only", *only])
    printed = capsys.readouterr().out
    assert_as_recorded("standin_camera", printed, only=lambda line: line.startswith(only[0]))
    readme = docs_pages.text()
    pattern = (
        r"(\d+): (\d+) runs, z (\S+) (\S+) (\S+), camera (\S+) mm (\S+) deg, k \S+ m, "
        r"delay (\S+) \+- (\S+) ms"
    )
    lines = [re.match(pattern, line) for line in printed.splitlines()]
    lines = [line for line in lines if line]
    assert [line.group(1) for line in lines] == only
    for line in lines:
        name, runs, a, b, c, mm, deg, delay, spread = line.groups()
        assert abs(float(mm) - 10.0) <= 0.6
        assert abs(float(delay) - 50.0) <= 3 * float(spread)
        row = f"| {name} | {runs} | {a}, {b}, {c} | {mm} mm, {deg} deg | {delay} +- {spread} ms |"
        assert row in readme, row
    # The held-out target (1.10) missed here as on all ten, and the precision this camera
    # allows would miss it too (9.4 and 6.5 mm against 5.6 mm: 1.68 and 1.16 times).
    assert found["folds"] == 6
    assert found["ratio"] == pytest.approx(1.68, abs=0.01)
    assert found["bound"] == pytest.approx(1.16, abs=0.01)
