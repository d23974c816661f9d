"""The numbers behind each section of the learning page, computed by the library itself.

Each function takes what a student sets on the page and returns a lesson: the library's values
and a ``markdown()`` text that writes them into the notes' formulas (seeds 000 to 004). The page
(``diffdrive.learn.page``) only lays these out beside the pictures of ``diffdrive.learn.drawings``,
so everything it shows can be checked here as plain Python.

Numbers shown on the page carry a ``data-testid`` (``fmt_id``), so that a browser test can read
them back and compare them with the library.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from diffdrive import integrate, se2
from diffdrive._validate import whole
from diffdrive.control.commands import Keep, desaturate
from diffdrive.integrate import METHODS, Method
from diffdrive.model import DiffDrive
from diffdrive.simulation import integrate_increments, simulate
from diffdrive.types import Pose, Twist, WheelVelocities

__all__ = [
    "CheckLesson",
    "ForwardLesson",
    "IntegrationLesson",
    "InverseLesson",
    "ModernRoboticsLesson",
    "check_answer",
    "fmt",
    "fmt_id",
    "forward_lesson",
    "integration_lesson",
    "inverse_lesson",
    "modern_robotics_lesson",
]

# The half-track symbols of the notes, with the seeds that use each.
HALF_TRACK_SYMBOLS = (("b", "000"), ("d", "001, 002"), ("D", "001"), ("L", "003, 004"))


def fmt(value: float, digits: int = 6) -> str:
    """A number for the page: ``digits`` significant digits, infinities and NaN spelled out."""
    if math.isnan(value):
        return "undefined"
    if math.isinf(value):
        return "+inf" if value > 0 else "-inf"
    text = f"{value:.{digits}g}"
    return "0" if text == "-0" else text


def fmt_id(test_id: str, value: float, digits: int = 6) -> str:
    """``fmt(value)`` in a span that a browser test finds as ``dd-{test_id}`` (the prefix keeps
    clear of marimo's own test ids, such as its sliders' ``track``)."""
    return f'<span data-testid="dd-{test_id}">{fmt(value, digits)}</span>'


def _tex(value: float) -> str:
    """A number inside a LaTeX formula."""
    text = fmt(value, 4)
    return {"+inf": r"+\infty", "-inf": r"-\infty", "undefined": r"\text{undefined}"}.get(
        text, text
    )


def _pmatrix(matrix: np.ndarray) -> str:
    rows = [" & ".join(_tex(float(v)) for v in row) for row in np.atleast_2d(matrix)]
    return r"\begin{pmatrix}" + r" \\ ".join(rows) + r"\end{pmatrix}"


# -- 1. geometry and forward kinematics --------------------------------------------------------


@dataclass(frozen=True)
class ForwardLesson:
    """Wheel speeds to the chassis: seeds 002 and 003."""

    robot: DiffDrive
    wheels: WheelVelocities
    twist: Twist
    turning_radius: float
    center: tuple[float, float]

    @property
    def rim_speeds(self) -> tuple[float, float]:
        """``(V_L, V_R)``, m/s: seed 002's wheel rim speeds ``r * phi_dot``."""
        return (
            self.robot.left_wheel_radius * self.wheels.left,
            self.robot.right_wheel_radius * self.wheels.right,
        )

    @property
    def matrix(self) -> np.ndarray:
        """Seed 003's 2x2 matrix from ``[phi_dot_L, phi_dot_R]`` to ``[x_dot, theta_dot]``."""
        return self.robot.to_twist_matrix()

    def markdown(self) -> str:
        """The lesson's text in Markdown with LaTeX, its numbers from the library."""
        r = self.robot.wheel_radius
        half = self.robot.half_track
        v_l, v_r = self.rim_speeds
        symbols = ", ".join(f"${s}$ (seed {seeds})" for s, seeds in HALF_TRACK_SYMBOLS)
        return "\n\n".join(
            [
                f"**Half track.** The notes write half the track as {symbols}: here "
                f"$L = {_tex(half)}$ m = {fmt_id('half-track', half)} m, so the full track "
                f"(wheel to wheel, `track_width`) is {fmt_id('track', self.robot.track_width)} m.",
                f"**Wheels:** r = {fmt_id('radius', r)} m, "
                f"left {fmt_id('left', self.wheels.left)} rad/s, "
                f"right {fmt_id('right', self.wheels.right)} rad/s.",
                f"**Rim speeds** (seed 002): $V_L = r\\dot\\varphi_L = {_tex(r)}\\times"
                f"{_tex(self.wheels.left)} = {_tex(v_l)}$ m/s, "
                f"$V_R = r\\dot\\varphi_R = {_tex(r)}\\times{_tex(self.wheels.right)} = "
                f"{_tex(v_r)}$ m/s.",
                f"$$v = \\frac{{V_R + V_L}}{{2}} = {_tex(self.twist.vx)}\\ \\mathrm{{m/s}}, "
                f"\\qquad \\omega = \\frac{{V_R - V_L}}{{2L}} = {_tex(self.twist.omega)}"
                "\\ \\mathrm{rad/s}$$",
                f"v = {fmt_id('v', self.twist.vx)} m/s, "
                f"ω = {fmt_id('omega', self.twist.omega)} rad/s.",
                "**Seed 003's matrix**, with these numbers:",
                f"$$\\begin{{pmatrix}}\\dot x\\\\"
                f"\\dot\\theta\\end{{pmatrix}} = \\begin{{pmatrix}} r/2 & r/2 \\\\ -r/(2L) & "
                f"r/(2L)\\end{{pmatrix}}\\begin{{pmatrix}}\\dot\\varphi_L\\\\ \\dot\\varphi_R"
                f"\\end{{pmatrix}} = {_pmatrix(self.matrix)}"
                f"{_pmatrix(np.array([[self.wheels.left], [self.wheels.right]]))} = "
                f"{_pmatrix(np.array([[self.twist.vx], [self.twist.omega]]))}$$",
                f"**Turning radius** (seed 002): $R = \\frac{{v}}{{\\omega}} = "
                f"L\\,\\frac{{V_R + V_L}}{{V_R - V_L}} = {_tex(self.turning_radius)}$ m: "
                f"R = {fmt_id('turning-radius', self.turning_radius)} m. "
                f"The centre of curvature is at body $(x, y) = (0, R)$, on the axle line. "
                + _turning_words(self.twist),
                "*Conventions that bite here:* the **left** wheel is on the robot's +y side; "
                "ω > 0 turns **left** (counter-clockwise) and puts the centre on the left "
                "(R > 0); R = ±inf driving straight, 0 spinning in place, undefined standing "
                "still.",
            ]
        )


def _turning_words(twist: Twist) -> str:
    if twist.omega == 0.0:
        return "Driving straight: the centre is at infinity." if twist.vx else "Standing still."
    side = "left (counter-clockwise)" if twist.omega > 0 else "right (clockwise)"
    return f"The robot turns {side}."


def forward_lesson(
    wheel_radius: float, track_width: float, left: float, right: float
) -> ForwardLesson:
    """Section 1: radius ``r`` (m), full ``track_width`` (m), wheel speeds (rad/s)."""
    robot = DiffDrive(wheel_radius, track_width)
    wheels = WheelVelocities(left, right)
    return ForwardLesson(
        robot=robot,
        wheels=wheels,
        twist=robot.to_twist(wheels),
        turning_radius=robot.turning_radius(wheels),
        center=robot.instantaneous_center(wheels),
    )


# -- 2. inverse kinematics and desaturation ----------------------------------------------------


@dataclass(frozen=True)
class InverseLesson:
    """A desired ``(v, omega)`` to wheel speeds (seeds 001, 003), then within a wheel limit."""

    robot: DiffDrive
    twist: Twist
    wheels: WheelVelocities
    limit: float
    keep: Keep
    delivered_wheels: WheelVelocities
    delivered: Twist

    @property
    def saturated(self) -> bool:
        """Whether a wheel would exceed the limit, so the command was scaled back."""
        return self.delivered_wheels != self.wheels

    def markdown(self) -> str:
        """The lesson's text in Markdown with LaTeX, its numbers from the library."""
        r, half = self.robot.wheel_radius, self.robot.half_track
        v, w = self.twist.vx, self.twist.omega
        lines = [
            "Seed 001 (conventional wheels, $D$ = half track) and seed 003's inverse matrix:",
            f"$$\\dot\\varphi_L = \\frac{{\\dot x - L\\dot\\theta}}{{r}} = "
            f"\\frac{{{_tex(v)} - {_tex(half)}\\times{_tex(w)}}}{{{_tex(r)}}} = "
            f"{_tex(self.wheels.left)},\\qquad \\dot\\varphi_R = \\frac{{\\dot x + "
            f"L\\dot\\theta}}{{r}} = {_tex(self.wheels.right)}\\ \\mathrm{{rad/s}}$$",
            f"Wheels: left {fmt_id('ik-left', self.wheels.left)}, right "
            f"{fmt_id('ik-right', self.wheels.right)} rad/s; limit ±{fmt(self.limit)} rad/s.",
        ]
        if not self.saturated:
            lines.append("Both wheels are within the limit: the command goes out as it is.")
        else:
            lines.append(
                f"A wheel is over the limit, so `desaturate(keep={self.keep!r})` brings both "
                f"back: left {fmt_id('sat-left', self.delivered_wheels.left)}, right "
                f"{fmt_id('sat-right', self.delivered_wheels.right)} rad/s, which drive "
                f"v = {fmt(self.delivered.vx)} m/s and ω = {fmt(self.delivered.omega)} rad/s."
            )
            lines.append(_kept_words(self.twist, self.delivered, self.keep))
        return "\n\n".join(lines)


def _curvature(twist: Twist) -> float:
    return twist.omega / twist.vx if twist.vx else math.copysign(math.inf, twist.omega)


def _kept_words(asked: Twist, got: Twist, keep: Keep) -> str:
    asked_k, got_k = _curvature(asked), _curvature(got)
    text = (
        f"Curvature κ = ω/v: asked {fmt(asked_k)} 1/m, delivered "
        f"{fmt_id('sat-curvature', got_k)} 1/m"
    )
    if keep == "curvature":
        return text + (
            ". Scaling both wheels by the same factor keeps the curvature, so the robot "
            "follows the same circle, only slower."
        )
    return text + f". Keeping {keep} instead bends the path: the robot leaves the asked circle."


def inverse_lesson(
    wheel_radius: float,
    track_width: float,
    v: float,
    omega: float,
    limit: float,
    keep: Keep = "curvature",
) -> InverseLesson:
    """Section 2: desired ``v`` (m/s), ``omega`` (rad/s) and a wheel limit (rad/s)."""
    robot = DiffDrive(wheel_radius, track_width)
    twist = Twist(v, 0.0, omega)
    wheels = robot.to_wheel_velocities(twist)
    delivered = desaturate(wheels, limit, keep=keep, robot=robot)
    return InverseLesson(
        robot=robot,
        twist=twist,
        wheels=wheels,
        limit=limit,
        keep=keep,
        delivered_wheels=delivered,
        delivered=robot.to_twist(delivered),
    )


# -- 3. the Modern Robotics form ---------------------------------------------------------------


@dataclass(frozen=True)
class ModernRoboticsLesson:
    """Wheel frames, ``H``, its pseudo-inverse and the true inverse (seeds 001, 004)."""

    robot: DiffDrive
    wheels: WheelVelocities

    @property
    def h(self) -> np.ndarray:
        """2x3 ``H``: ``[wl, wr] = H V_b`` with ``V_b = (omega, vx, vy)``."""
        return self.robot.h_matrix()

    @property
    def q(self) -> np.ndarray:
        """2x3 no-slip constraint ``Q V_b = 0``."""
        return self.robot.constraint_matrix()

    @property
    def pinv(self) -> np.ndarray:
        """3x2 seed 004 pseudo-inverse ``H^T (H H^T)^-1``."""
        return self.robot.pseudo_inverse_matrix()

    @property
    def true_twist(self) -> np.ndarray:
        """``V_b = F u``, Modern Robotics order: the twist the wheels really drive."""
        return self.robot.f_matrix() @ self.wheels.to_array()

    @property
    def pinv_twist(self) -> np.ndarray:
        """``V_b = H+ u``: right on the axle, sliding sideways off it."""
        return self.pinv @ self.wheels.to_array()

    @property
    def pinv_slip(self) -> np.ndarray:
        """``Q H+ u``, m/s: each wheel's sideways speed if the robot moved by ``H+ u``."""
        return self.q @ self.pinv_twist

    def markdown(self) -> str:
        """The lesson's text in Markdown with LaTeX, its numbers from the library."""
        d = self.robot.axle_offset
        left, right = self.robot.wheel_frames()
        frames = ", ".join(
            f"$T_{{b{side}}} = (\\phi, x, y) = ({_tex(f.theta)}, {_tex(f.x)}, {_tex(f.y)})$"
            for side, f in (("l", left), ("r", right))
        )
        true, pinv = self.true_twist, self.pinv_twist
        wheels = _pmatrix(np.array([[self.wheels.left], [self.wheels.right]]))
        return "\n\n".join(
            [
                f"Reference point $D = {_tex(d)}$ m ahead of the axle. Wheel frames: {frames} "
                "(our left wheel on +y; seed 004 labels the sides the other way round).",
                f"$$H = {_pmatrix(self.h)},\\qquad Q = {_pmatrix(self.q)},\\qquad "
                f"H^+ = H^T(HH^T)^{{-1}} = {_pmatrix(self.pinv)}$$",
                f"$$V_b = F u = {_pmatrix(self.robot.f_matrix())}{wheels} = "
                f"{_pmatrix(true[:, None])},\\qquad H^+ u = {_pmatrix(pinv[:, None])}$$",
                f"The true map gives $v_y = D\\omega$ = {fmt_id('true-vy', float(true[2]))} m/s "
                f"and no sideways slip at the wheels. The pseudo-inverse gives $v_y$ = "
                f"{fmt_id('pinv-vy', float(pinv[2]))} m/s: moving that way, the wheels would "
                f"slide sideways at {fmt_id('pinv-slip', float(self.pinv_slip[0]))} m/s "
                f"($Q H^+ u$). The two agree only when $D = 0$ or the robot drives straight.",
            ]
        )


def modern_robotics_lesson(
    wheel_radius: float, track_width: float, axle_offset: float, left: float, right: float
) -> ModernRoboticsLesson:
    """Section 3: the reference point ``axle_offset`` m ahead of the axle."""
    robot = DiffDrive(wheel_radius, track_width, axle_offset=axle_offset)
    return ModernRoboticsLesson(robot=robot, wheels=WheelVelocities(left, right))


# -- 4. integration ----------------------------------------------------------------------------

STEP_FORMULAS: dict[Method, str] = {
    "euler": r"x_{k+1} = x_k + h\,v\cos\theta_k,\quad y_{k+1} = y_k + h\,v\sin\theta_k,"
    r"\quad \theta_{k+1} = \theta_k + h\,\omega",
    "rk2": r"x_{k+1} = x_k + h\,v\cos(\theta_k + \tfrac{h\omega}{2}),\quad "
    r"y_{k+1} = y_k + h\,v\sin(\theta_k + \tfrac{h\omega}{2}),\quad "
    r"\theta_{k+1} = \theta_k + h\,\omega",
    "exact": r"x_{k+1} = x_k + h\,v\,\mathrm{sinc}(\tfrac{h\omega}{2})\cos(\theta_k + "
    r"\tfrac{h\omega}{2}),\quad y_{k+1} = y_k + h\,v\,\mathrm{sinc}(\tfrac{h\omega}{2})"
    r"\sin(\theta_k + \tfrac{h\omega}{2})\ \ (T_{bb'} = e^{[V_b]h})",
}


@dataclass(frozen=True)
class IntegrationLesson:
    """One constant-wheel-speed history integrated three ways against the exact arc."""

    robot: DiffDrive
    twist: Twist
    duration: float
    step: float
    paths: dict[Method, np.ndarray]  # (n+1, 3) poses of each method
    arc: np.ndarray  # (m, 3) poses along the exact arc, finely sampled

    @property
    def end(self) -> Pose:
        """The exact end pose: seed 001's ``T_bb'`` over the whole duration."""
        return Pose().compose(se2.exp(self.twist, self.duration))

    def errors(self) -> dict[Method, float]:
        """Each method's end-position error against the exact arc, m."""
        end = self.end
        return {m: math.hypot(p[-1, 0] - end.x, p[-1, 1] - end.y) for m, p in self.paths.items()}

    def convergence(self, count: int = 12) -> tuple[np.ndarray, dict[Method, np.ndarray]]:
        """End-position errors (m) of each method for ``count`` step sizes from the whole
        duration down to 1/1000 of it: ``(steps, {method: errors})``."""
        counts = np.unique(np.geomspace(1, 1000, count).round().astype(int))
        errors = {
            m: np.array(
                [_end_error(self.robot, self.twist, self.duration, int(n), m) for n in counts]
            )
            for m in METHODS
        }
        return self.duration / counts, errors

    def markdown(self) -> str:
        """The lesson's text in Markdown with LaTeX, its numbers from the library."""
        n = len(self.paths["exact"]) - 1
        rows = [
            "| method | one step | end-position error (m) |",
            "|---|---|---|",
        ]
        for method, error in self.errors().items():
            rows.append(
                f"| {method} | ${STEP_FORMULAS[method]}$ | {fmt_id(f'error-{method}', error, 3)} |"
            )
        return "\n\n".join(
            [
                f"{n} steps of $h$ = {fmt_id('step', self.step)} s over {fmt(self.duration)} s "
                f"at v = {fmt(self.twist.vx)} m/s, ω = {fmt(self.twist.omega)} rad/s. The exact "
                f"arc ends at $(x, y, \\theta) = ({_tex(self.end.x)}, {_tex(self.end.y)}, "
                f"{_tex(self.end.theta)})$.",
                "\n".join(rows),
                "Halving $h$ halves Euler's error (first order) and quarters rk2's (second "
                "order); the exact step follows the arc whatever $h$, because the wheel speeds "
                "are constant over each step.",
            ]
        )


def _end_error(robot: DiffDrive, twist: Twist, duration: float, n: int, method: Method) -> float:
    end = se2.exp(twist, duration)
    increments = np.tile([twist.vx, twist.vy, twist.omega], (n, 1)) * (duration / n)
    last = integrate_increments(increments, method=method)[-1]
    return math.hypot(last[0] - end.x, last[1] - end.y)


def integration_lesson(
    wheel_radius: float,
    track_width: float,
    left: float,
    right: float,
    duration: float,
    step: float,
) -> IntegrationLesson:
    """Section 4: wheel speeds (rad/s) held for ``duration`` s, integrated in steps of ``step``."""
    robot = DiffDrive(wheel_radius, track_width)
    twist = robot.to_twist((left, right))
    n = max(1, round(duration / step))
    history = np.tile([left, right], (n, 1))
    paths = {
        m: simulate(robot, history, dt=duration / n, method=m, backend="numpy").poses
        for m in METHODS
    }
    fine = np.linspace(0.0, duration, 200)
    arc = np.array([Pose().compose(se2.exp(twist, t)).to_array() for t in fine])
    return IntegrationLesson(robot, twist, duration, duration / n, paths, arc)


# -- 5. check my answer ------------------------------------------------------------------------

TrackMeaning = Literal["half", "full"]


@dataclass(frozen=True)
class CheckLesson:
    """k Euler steps of seeds 000 and 002, each written out, and the exact pose after k T."""

    robot: DiffDrive
    twist: Twist
    step: float
    poses: list[Pose]  # the Euler poses after 0..k steps, from integrate.step
    exact: Pose

    def markdown(self) -> str:
        """The lesson's text in Markdown with LaTeX, its numbers from the library."""
        v, w, h = self.twist.vx, self.twist.omega, self.step
        r, half = self.robot.wheel_radius, self.robot.half_track
        lines = [
            "Seed 002's discrete model with step $T$ and heading $\\theta$ (seed 000 writes "
            "them $h$ and $\\alpha$).",
            f"With $r = {_tex(r)}$ m and $L = {_tex(half)}$ m (half track): "
            f"$v = \\frac{{r}}{{2}}(\\dot\\varphi_R + \\dot\\varphi_L) = {_tex(v)}$ m/s, "
            f"$\\omega = \\frac{{r}}{{2L}}(\\dot\\varphi_R - \\dot\\varphi_L) = {_tex(w)}$ "
            f"rad/s: v = {fmt_id('check-v', v)}, ω = {fmt_id('check-omega', w)}.",
        ]
        table = [
            "| k | $x(k+1) = x(k) + T v \\cos\\theta(k)$ | $y(k+1) = y(k) + T v \\sin\\theta(k)$"
            " | $\\theta(k+1) = \\theta(k) + T\\omega$ |",
            "|---|---|---|---|",
        ]
        for k, (now, after) in enumerate(zip(self.poses, self.poses[1:], strict=False)):
            table.append(
                f"| {k} | {_tex_cell(now.x, h, v, 'cos', now.theta, after.x)} | "
                f"{_tex_cell(now.y, h, v, 'sin', now.theta, after.y)} | "
                f"${_tex(now.theta)} + {_tex(h)}\\times{_tex(w)} = {_tex(after.theta)}$ |"
            )
        lines.append("\n".join(table))
        last, k = self.poses[-1], len(self.poses) - 1
        lines.append(
            f"**After k = {k} Euler steps:** x = {fmt_id('euler-x', last.x)} m, "
            f"y = {fmt_id('euler-y', last.y)} m, θ = {fmt_id('euler-theta', last.theta)} rad."
        )
        lines.append(
            f"**Exact pose after kT = {fmt(k * h)} s** (the arc, seed 001's $T_{{bb'}}$): "
            f"x = {fmt_id('exact-x', self.exact.x)} m, y = {fmt_id('exact-y', self.exact.y)} m, "
            f"θ = {fmt_id('exact-theta', self.exact.theta)} rad. Euler is "
            f"{fmt(math.hypot(last.x - self.exact.x, last.y - self.exact.y), 3)} m off."
        )
        return "\n\n".join(lines)


def _tex_cell(start: float, h: float, v: float, trig: str, theta: float, result: float) -> str:
    return (
        f"${_tex(start)} + {_tex(h)}\\times{_tex(v)}\\times\\{trig}({_tex(theta)}) = "
        f"{_tex(result)}$"
    )


def check_answer(
    wheel_radius: float,
    track: float,
    track_meaning: TrackMeaning,
    left: float,
    right: float,
    step: float,
    steps: int | float,
    initial: Pose | tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> CheckLesson:
    """Section 5: ``track`` is the half track (the notes' b, d, D, L) or the full one."""
    if track_meaning not in ("half", "full"):
        raise ValueError(f"track_meaning must be 'half' or 'full', got {track_meaning!r}")
    steps = whole("the number of steps k", steps, smallest=1)
    if track_meaning == "half":
        robot = DiffDrive(wheel_radius, half_track=track)
    else:
        robot = DiffDrive(wheel_radius, track)
    twist = robot.to_twist((left, right))
    poses = [Pose.coerce(initial, "initial")]
    for _ in range(steps):
        poses.append(integrate.step(poses[-1], twist, step, "euler"))
    exact = integrate.step(poses[0], twist, steps * step, "exact")
    return CheckLesson(robot, twist, step, poses, exact)
