"""The pictures of the learning page: one matplotlib figure per section, from its lesson.

Figures are made with ``matplotlib.figure.Figure`` directly, so drawing never touches pyplot's
global state or the backend of the process that imports this module.
"""

from __future__ import annotations

import math

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Circle, Rectangle

from diffdrive.learn.lessons import (
    CheckLesson,
    ForwardLesson,
    IntegrationLesson,
    InverseLesson,
    ModernRoboticsLesson,
)
from diffdrive.model import DiffDrive
from diffdrive.se2 import exp
from diffdrive.types import Twist

__all__ = [
    "check_picture",
    "forward_picture",
    "integration_picture",
    "inverse_picture",
    "modern_robotics_picture",
]

ASKED, DELIVERED, TRUE, WRONG = "tab:blue", "tab:orange", "tab:green", "tab:red"
METHOD_COLOURS = {"euler": "tab:red", "rk2": "tab:orange", "exact": "tab:green"}


def _robot(ax, robot: DiffDrive) -> None:
    """The robot seen from above in its body frame (x forward, y left): chassis and wheels,
    the wheels on the axle ``axle_offset`` m behind the reference point at the origin."""
    half, r, back = robot.half_track, robot.wheel_radius, robot.axle_offset
    ax.add_patch(
        Rectangle((-back - 0.6 * half, -0.8 * half), 1.6 * half, 1.6 * half, fc="0.92", ec="0.4")
    )
    for side, y in (("left", half), ("right", -half)):
        ax.add_patch(Rectangle((-back - r, y - 0.08 * half), 2 * r, 0.16 * half, fc="0.2"))
        ax.annotate(
            side,
            (-back, y),
            xytext=(-back, y + math.copysign(0.22 * half, y)),
            ha="center",
            va="center",
            fontsize=8,
        )
    ax.plot([-back], [0.0], "k+", ms=8)  # axle midpoint
    ax.plot([0.0], [0.0], "ko", ms=4)  # reference point


def _arrow(ax, x: float, y: float, dx: float, dy: float, colour: str, label: str | None = None):
    if dx or dy:
        ax.annotate(
            "", (x + dx, y + dy), (x, y), arrowprops={"arrowstyle": "->", "color": colour, "lw": 2}
        )
    if label:
        ax.plot([], [], color=colour, lw=2, label=label)


def _frame(ax, span: float) -> None:
    ax.set_aspect("equal")
    ax.set_xlim(-span, span)
    ax.set_ylim(-span, span)
    ax.grid(True, alpha=0.3)
    ax.set_xlabel("body x (m), forward")
    ax.set_ylabel("body y (m), left")


def _plane(ax) -> None:
    """World-frame axes for paths: equal scale, metres, a legend."""
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)


def forward_picture(lesson: ForwardLesson) -> Figure:
    """Section 1: the wheels' rim speeds, the chassis velocity and the centre of curvature."""
    robot, half = lesson.robot, lesson.robot.half_track
    fig = Figure(figsize=(5.0, 5.0), layout="constrained")
    ax = fig.add_subplot()
    radius = lesson.turning_radius
    # Wide enough to show the centre of curvature unless it is far away (> 8.5 half tracks).
    near = abs(radius) if math.isfinite(radius) else 0.0
    span = max(2.5 * half, min(near + 1.5 * half, 10 * half))
    _robot(ax, robot)
    v_l, v_r = lesson.rim_speeds
    scale = 1.5 * half / max(abs(v_l), abs(v_r), abs(lesson.twist.vx), 1e-12)
    _arrow(ax, 0.0, half, scale * v_l, 0.0, ASKED, "rim speeds V_L, V_R")
    _arrow(ax, 0.0, -half, scale * v_r, 0.0, ASKED)
    _arrow(ax, 0.0, 0.0, scale * lesson.twist.vx, 0.0, TRUE, "v")
    if math.isfinite(radius):
        ax.add_patch(Circle((0.0, radius), abs(radius), fill=False, ls="--", ec=TRUE))
        if abs(radius) < span:
            ax.plot([0.0], [radius], "o", color=WRONG, label=f"centre (0, R), R = {radius:.3g} m")
            ax.plot([0, 0], [half, -half], ":", color=WRONG)
        else:
            y = math.copysign(0.9 * span, radius)
            ax.annotate(f"centre at y = {radius:.3g} m", (0.0, y), ha="center", color=WRONG)
    else:
        ax.set_title("no centre: " + ("driving straight" if lesson.twist.vx else "standing still"))
    _frame(ax, span)
    ax.legend(loc="lower left", fontsize=8)
    return fig


def _drive(twist: Twist, duration: float, count: int = 100) -> np.ndarray:
    times = np.linspace(0.0, duration, count)
    return np.array([exp(twist, t).to_array() for t in times])


def inverse_picture(lesson: InverseLesson) -> Figure:
    """Section 2: the wheel-speed plane with its limit square, and 2 s of the two paths."""
    fig = Figure(figsize=(9.0, 4.2), layout="constrained")
    wheels, paths = fig.add_subplot(1, 2, 1), fig.add_subplot(1, 2, 2)
    asked, got, limit = lesson.wheels.to_array(), lesson.delivered_wheels.to_array(), lesson.limit
    reach = 1.3 * max(limit, float(np.max(np.abs(asked))))
    wheels.add_patch(
        Rectangle(
            (-limit, -limit),
            2 * limit,
            2 * limit,
            fill=False,
            ec="0.3",
            ls="--",
            label="wheel limit",
        )
    )
    if np.any(asked):
        wheels.plot(
            [0, 1.5 * asked[0]], [0, 1.5 * asked[1]], ":", color="0.5", label="same curvature"
        )
    wheels.plot(*asked, "o", color=ASKED, label="asked")
    wheels.plot(*got, "s", color=DELIVERED, mfc="none", ms=10, label="delivered")
    wheels.set_aspect("equal")
    wheels.set_xlim(-reach, reach)
    wheels.set_ylim(-reach, reach)
    wheels.set_xlabel("left wheel (rad/s)")
    wheels.set_ylabel("right wheel (rad/s)")
    wheels.grid(True, alpha=0.3)
    wheels.legend(loc="lower right", fontsize=8)
    for twist, colour, name in (
        (lesson.twist, ASKED, "asked"),
        (lesson.delivered, DELIVERED, "delivered"),
    ):
        path = _drive(twist, 2.0)
        paths.plot(path[:, 0], path[:, 1], color=colour, label=f"{name}, 2 s")
    _plane(paths)
    return fig


def modern_robotics_picture(lesson: ModernRoboticsLesson) -> Figure:
    """Section 3: the reference point's velocity from ``F`` and from ``H+``, and the sideways
    slip of the wheels that ``H+``'s twist would need."""
    robot = lesson.robot
    half = robot.half_track
    fig = Figure(figsize=(5.0, 5.0), layout="constrained")
    ax = fig.add_subplot()
    span = 2.5 * half + abs(robot.axle_offset)
    _robot(ax, robot)
    true, pinv = lesson.true_twist, lesson.pinv_twist
    scale = 1.5 * half / max(float(np.max(np.abs(true[1:]))), 1e-12)
    _arrow(ax, 0.0, 0.0, scale * true[1], scale * true[2], TRUE, "F u: the true twist")
    _arrow(ax, 0.0, 0.0, scale * pinv[1], scale * pinv[2], WRONG, "H+ u")
    for slip, frame in zip(lesson.pinv_slip, robot.wheel_frames(), strict=True):
        _arrow(ax, frame.x, frame.y, 0.0, scale * slip, "tab:purple")
    ax.plot([], [], color="tab:purple", lw=2, label="wheel slip under H+ u")
    _frame(ax, span)
    ax.legend(loc="lower left", fontsize=8)
    return fig


def integration_picture(lesson: IntegrationLesson) -> Figure:
    """Section 4: the three stepped paths on the exact arc, and each method's error against
    the step size."""
    fig = Figure(figsize=(9.0, 4.2), layout="constrained")
    paths, errors = fig.add_subplot(1, 2, 1), fig.add_subplot(1, 2, 2)
    paths.plot(lesson.arc[:, 0], lesson.arc[:, 1], color="0.6", lw=4, label="exact arc")
    for method, poses in lesson.paths.items():
        paths.plot(poses[:, 0], poses[:, 1], ".-", color=METHOD_COLOURS[method], label=method)
    _plane(paths)
    steps, curves = lesson.convergence()
    tiny = np.finfo(float).eps  # rounding: the floor of a log axis
    for method, curve in curves.items():
        errors.loglog(
            steps, np.maximum(curve, tiny), "o-", ms=3, color=METHOD_COLOURS[method], label=method
        )
    errors.axvline(lesson.step, color="0.3", ls="--", label="this h")
    errors.set_xlabel("step h (s)")
    errors.set_ylabel("end-position error (m)")
    errors.grid(True, which="both", alpha=0.3)
    errors.legend(fontsize=8)
    return fig


def check_picture(lesson: CheckLesson) -> Figure:
    """Section 5: the Euler poses of the table on the exact arc."""
    fig = Figure(figsize=(5.0, 4.0), layout="constrained")
    ax = fig.add_subplot()
    start = lesson.poses[0]
    duration = lesson.step * (len(lesson.poses) - 1)
    arc = np.array(
        [start.compose(exp(lesson.twist, t)).to_array() for t in np.linspace(0, duration, 100)]
    )
    ax.plot(arc[:, 0], arc[:, 1], color="0.6", lw=4, label="exact arc")
    euler = np.array([p.to_array() for p in lesson.poses])
    ax.plot(euler[:, 0], euler[:, 1], "o-", color=METHOD_COLOURS["euler"], label="Euler steps")
    for k, pose in enumerate(lesson.poses):
        ax.annotate(str(k), (pose.x, pose.y), textcoords="offset points", xytext=(4, 4), fontsize=8)
    end = lesson.exact
    ax.plot([end.x], [end.y], "*", ms=12, color=METHOD_COLOURS["exact"], label="exact pose")
    _plane(ax)
    return fig
