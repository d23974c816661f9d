"""The learning page's lessons, pictures and cells, as plain Python (the browser test drives the
served page: test_learn_browser.py)."""

import importlib.util
import math
import re
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from diffdrive import DiffDrive, Pose, simulate
from diffdrive.learn import lessons, missing_extra


def _draws_a_figure(picture: str, lesson) -> bool:
    """Whether the drawing ``picture`` of ``lesson`` is a matplotlib Figure. Matplotlib is
    imported here, not at collection (0.7 s)."""
    from matplotlib.figure import Figure

    from diffdrive.learn import drawings

    return isinstance(getattr(drawings, picture)(lesson), Figure)


# Skipped without marimo, found without importing it (its import takes over a second).
pytestmark = pytest.mark.skipif(
    importlib.util.find_spec("marimo") is None,
    reason="marimo (the learn extra) is in the test group",
)


def shown(markdown: str, test_id: str) -> float:
    """The number a lesson shows under ``test_id``."""
    match = re.search(rf'data-testid="dd-{test_id}">([^<]+)<', markdown)
    assert match, f"{test_id} is not on the page"
    return float(match.group(1))


# -- 1. forward kinematics: r = 0.05 m, track 0.3 m (L = 0.15), wheels 4 and 10 rad/s ---------
# V_L = 0.2, V_R = 0.5 m/s; v = 0.35 m/s; omega = 0.3 / 0.3 = 1 rad/s; R = v / omega = 0.35 m.


def test_forward_lesson_shows_the_seed_002_and_003_numbers():
    lesson = lessons.forward_lesson(0.05, 0.3, 4.0, 10.0)
    assert lesson.rim_speeds == pytest.approx((0.2, 0.5))
    assert lesson.twist.vx == pytest.approx(0.35)
    assert lesson.twist.omega == pytest.approx(1.0)
    assert lesson.turning_radius == pytest.approx(0.35)
    assert lesson.center == pytest.approx((0.0, 0.35))
    np.testing.assert_allclose(lesson.matrix, [[0.025, 0.025], [-1 / 6, 1 / 6]])
    text = lesson.markdown()
    assert shown(text, "half-track") == pytest.approx(0.15)
    assert shown(text, "turning-radius") == pytest.approx(0.35)
    assert shown(text, "omega") == pytest.approx(1.0)
    for symbol in ("$b$", "$d$", "$D$", "$L$"):
        assert symbol in text  # every half-track symbol of the notes is named
    assert "left** wheel is on the robot's +y side" in text


@pytest.mark.parametrize(
    ("left", "right", "radius_shown", "words"),
    [
        (5.0, 5.0, "+inf", "Driving straight"),
        (-5.0, -5.0, "-inf", "Driving straight"),
        (-5.0, 5.0, "0", "turns left"),
        (0.0, 0.0, "undefined", "Standing still"),
        (10.0, 4.0, "-0.35", "turns right"),
    ],
)
def test_forward_lesson_names_straight_spinning_and_standing_still(
    left, right, radius_shown, words
):
    lesson = lessons.forward_lesson(0.05, 0.3, left, right)
    text = lesson.markdown()
    assert f'data-testid="dd-turning-radius">{radius_shown}<' in text
    assert words in text
    assert _draws_a_figure("forward_picture", lesson)


# -- 2. inverse kinematics: v = 1 m/s, omega = 2 rad/s -> wheels (1 -+ 0.3) / 0.05 = 14, 26 -----


def test_inverse_lesson_desaturates_keeping_the_curvature():
    lesson = lessons.inverse_lesson(0.05, 0.3, 1.0, 2.0, limit=15.0)
    assert lesson.wheels.to_array() == pytest.approx([14.0, 26.0])
    assert lesson.saturated
    scale = 15.0 / 26.0
    assert lesson.delivered_wheels.to_array() == pytest.approx([14.0 * scale, 15.0])
    assert lesson.delivered.omega / lesson.delivered.vx == pytest.approx(2.0)
    text = lesson.markdown()
    assert shown(text, "sat-curvature") == pytest.approx(2.0)
    assert "same circle" in text
    assert _draws_a_figure("inverse_picture", lesson)


def test_inverse_lesson_within_the_limit_and_keeping_omega():
    within = lessons.inverse_lesson(0.05, 0.3, 0.5, 0.0, limit=15.0)
    assert not within.saturated
    assert "goes out as it is" in within.markdown()
    turn = lessons.inverse_lesson(0.05, 0.3, 1.0, 2.0, limit=15.0, keep="omega")
    assert turn.delivered.omega == pytest.approx(2.0)
    assert "bends the path" in turn.markdown()


# -- 3. the Modern Robotics form ----------------------------------------------------------------


def test_modern_robotics_lesson_shows_the_pseudo_inverse_sliding_sideways():
    lesson = lessons.modern_robotics_lesson(0.05, 0.3, 0.1, 4.0, 10.0)  # omega = 1, vx = 0.35
    assert lesson.true_twist == pytest.approx([1.0, 0.35, 0.1])  # vy = D omega
    assert lesson.pinv_twist == pytest.approx([1.0, 0.35, 0.0])
    assert lesson.pinv_slip == pytest.approx([-0.1, -0.1])  # Q H+ u: both wheels slide
    text = lesson.markdown()
    assert shown(text, "true-vy") == pytest.approx(0.1)
    assert shown(text, "pinv-slip") == pytest.approx(-0.1)
    assert _draws_a_figure("modern_robotics_picture", lesson)
    on_axle = lessons.modern_robotics_lesson(0.05, 0.3, 0.0, 4.0, 10.0)
    assert on_axle.pinv_twist == pytest.approx(on_axle.true_twist)
    assert on_axle.pinv_slip == pytest.approx([0.0, 0.0])


# -- 4. integration -----------------------------------------------------------------------------


def test_integration_lesson_orders_of_the_three_methods():
    coarse = lessons.integration_lesson(0.05, 0.3, 4.0, 10.0, duration=4.0, step=0.2)
    fine = lessons.integration_lesson(0.05, 0.3, 4.0, 10.0, duration=4.0, step=0.1)
    c, f = coarse.errors(), fine.errors()
    assert c["euler"] / f["euler"] == pytest.approx(2.0, rel=0.1)  # first order
    assert c["rk2"] / f["rk2"] == pytest.approx(4.0, rel=0.1)  # second order
    assert c["exact"] < 1e-12
    end = simulate(DiffDrive(0.05, 0.3), [[4.0, 10.0]], dt=4.0).poses[-1]  # one exact step
    assert coarse.end.to_array() == pytest.approx(end, abs=1e-12)
    steps, curves = coarse.convergence()
    assert np.all(np.diff(steps) < 0)
    assert np.all(np.diff(curves["euler"]) < 0)  # smaller steps, smaller errors
    assert shown(coarse.markdown(), "error-euler") == pytest.approx(c["euler"], rel=1e-2)
    assert _draws_a_figure("integration_picture", coarse)


def test_integration_rounds_the_step_to_whole_steps_and_says_so():
    lesson = lessons.integration_lesson(0.05, 0.3, 4.0, 10.0, duration=1.0, step=0.3)
    assert len(lesson.paths["euler"]) == 4  # 3 steps of 1/3 s
    assert shown(lesson.markdown(), "step") == pytest.approx(1 / 3, rel=1e-5)


# -- 5. check my answer: seed 000's recurrence by hand -------------------------------------------


def test_check_answer_table_is_seed_000_by_hand():
    lesson = lessons.check_answer(0.05, 0.15, "half", 8.0, 10.0, step=0.1, steps=3)
    v, w, h = 0.45, 1 / 3, 0.1
    x = y = theta = 0.0
    for pose in lesson.poses[1:]:
        x, y, theta = x + h * v * math.cos(theta), y + h * v * math.sin(theta), theta + h * w
        assert pose.to_array() == pytest.approx([x, y, theta], rel=1e-14)
    arc = 2 * v / w * math.sin(w * 0.3 / 2)  # chord of the exact arc
    assert lesson.exact.to_array() == pytest.approx(
        [arc * math.cos(0.05), arc * math.sin(0.05), 0.1], rel=1e-14
    )
    text = lesson.markdown()
    assert shown(text, "euler-x") == pytest.approx(x, rel=1e-5)
    assert shown(text, "exact-y") == pytest.approx(lesson.exact.y, rel=1e-5)
    assert r"0 + 0.1\times0.45\times\cos(0) = 0.045" in text  # each step written out
    assert _draws_a_figure("check_picture", lesson)


def test_check_answer_takes_the_half_or_the_full_track():
    half = lessons.check_answer(0.05, 0.15, "half", 8.0, 10.0, 0.1, 5, (1.0, 2.0, 0.5))
    full = lessons.check_answer(0.05, 0.30, "full", 8.0, 10.0, 0.1, 5, (1.0, 2.0, 0.5))
    assert half.poses == full.poses
    assert half.poses[0] == Pose(1.0, 2.0, 0.5)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        ((0.05, 0.15, "half", 8, 10, 0.1, 2.5), "whole number"),
        ((0.05, 0.15, "half", 8, 10, 0.1, 0), "whole number"),
        ((0.05, 0.15, "radius", 8, 10, 0.1, 3), "track_meaning"),
        ((0.0, 0.15, "half", 8, 10, 0.1, 3), "wheel_radius"),
        ((0.05, -0.15, "half", 8, 10, 0.1, 3), "half_track"),
    ],
)
def test_check_answer_refuses_what_it_cannot_compute(args, message):
    with pytest.raises(ValueError, match=message):
        lessons.check_answer(*args)


finite = st.floats(-20.0, 20.0, allow_nan=False)


@given(
    radius=st.floats(0.01, 0.5),
    half_track=st.floats(0.05, 1.0),
    left=finite,
    right=finite,
    step=st.floats(0.001, 1.0),
    steps=st.integers(1, 30),
)
def test_check_answer_agrees_with_simulate(radius, half_track, left, right, step, steps):
    lesson = lessons.check_answer(radius, half_track, "half", left, right, step, steps)
    robot = DiffDrive(radius, half_track=half_track)
    history = np.tile([left, right], (steps, 1))
    euler = simulate(robot, history, dt=step, method="euler", backend="numpy").poses[-1]
    exact = simulate(robot, history, dt=step, method="exact", backend="numpy").poses[-1]
    assert lesson.poses[-1].to_array() == pytest.approx(euler, abs=1e-9)
    assert lesson.exact.to_array() == pytest.approx(exact, abs=1e-9)


# -- the page's cells, run as plain Python ------------------------------------------------------


@pytest.mark.slow
def test_the_page_runs_as_plain_python_with_the_library_numbers():
    from diffdrive.learn import page

    outputs, defs = page.app.run()
    assert all(output is not None for output in outputs[-2:])
    robot = DiffDrive(defs["radius"].value, defs["track"].value)
    wheels = (defs["left"].value, defs["right"].value)
    assert defs["forward"].turning_radius == robot.turning_radius(wheels)
    assert defs["forward"].twist == robot.to_twist(wheels)
    assert defs["inverse"].wheels == robot.to_wheel_velocities(
        (defs["speed"].value, 0.0, defs["turn"].value)
    )
    assert defs["modern"].robot.axle_offset == defs["offset"].value
    assert defs["integration"].errors()["exact"] < 1e-12
    assert (
        defs["check"].poses[-1] == lessons.check_answer(0.05, 0.15, "half", 8, 10, 0.1, 3).poses[-1]
    )


def test_the_extra_is_named_when_it_is_missing(monkeypatch):
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util, "find_spec", lambda name: None if name == "marimo" else real(name)
    )
    reason = missing_extra()
    assert "marimo" in reason
    assert "diffdrive[learn]" in reason
    from diffdrive.cli import main

    assert main(["learn", "--no-browser"]) == 1


@pytest.mark.slow
def test_export_writes_a_static_page(tmp_path):
    out = tmp_path / "page.html"
    done = subprocess.run(
        [sys.executable, "-m", "diffdrive", "learn", "--export", str(out)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    text = out.read_text()
    assert "turning-radius" in text  # the outputs of the run are in the snapshot
    assert list(tmp_path.iterdir()) == [out]  # no scratch folder left behind


def test_export_into_a_missing_folder_is_refused(tmp_path, capsys):
    from diffdrive.cli import main

    assert main(["learn", "--export", str(tmp_path / "no" / "page.html")]) == 1
    assert "no such folder" in capsys.readouterr().err
