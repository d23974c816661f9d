"""Trackers: the twist that brings robots back onto a plan.

Every tracker answers ``command(plan, t, poses) -> twists``: ``poses`` ``(N, 3)`` where the
robots are (or are believed to be), ``t`` the time on the plan (s), and the twists ``(N, 2)``
``(v, omega)`` to command now. They are stateless, so one tracker serves a batch of robots.

- ``Ramsete``: the nonlinear unicycle law of Samson (1993) in WPILib's parameterisation, gains
  ``b`` and ``zeta``: ``k = 2 zeta sqrt(omega_r^2 + b v_r^2)``, ``v = v_r cos e_theta + k e_x``,
  ``omega = omega_r + k e_theta + b v_r sinc(e_theta) e_y``, the error in the robot's frame.
- ``LTVUnicycle``: the linear time-varying LQR of the unicycle's error linearised about the
  reference speed, ``A = [[0, 0, 0], [0, 0, v], [0, 0, 0]]``, ``B = [[1, 0], [0, 0], [0, 1]]``,
  discretised at ``dt``, gains from the discrete algebraic Riccati equation (scipy) on a table
  of speeds, with Bryson's weights ``Q = diag(1/q^2)``, ``R = diag(1/r^2)``.
- ``PurePursuit``: regulated pure pursuit (Macenski et al. 2023): a lookahead that grows with
  speed, the speed cut where the path bends tighter than ``min_radius``, and a turn in place
  when the lookahead point is too far off the heading.
- ``Predictive``: any tracker made to survive a known actuation delay and first-order lag: it
  predicts where each robot will be when the command takes effect, from the commands already
  sent (a Smith predictor on the kinematics), asks the tracker for the plan at that later time,
  and leads the lag by its time constant.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from diffdrive import batch
from diffdrive._optional import optional
from diffdrive._validate import finite, nonnegative, positive
from diffdrive.control.planning import Plan
from diffdrive.dynamics.lag import first_order

__all__ = [
    "LTVUnicycle",
    "Predictive",
    "PurePursuit",
    "Ramsete",
    "Tracker",
    "errors_in_robot",
]


class Tracker(Protocol):
    """What ``follow`` drives with."""

    def command(self, plan: Plan, t: float, poses: np.ndarray) -> np.ndarray:
        """Body twists ``(N, 2)`` ``(v, omega)`` for robots at ``poses`` ``(N, 3)`` tracking
        ``plan`` at time ``t`` s."""
        ...


def errors_in_robot(poses: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """``(N, 3)``: the reference pose ``(..., 3)`` seen from each robot's frame, the heading
    error wrapped to ``[-pi, pi)``."""
    dx, dy = reference[..., 0] - poses[..., 0], reference[..., 1] - poses[..., 1]
    c, s = np.cos(poses[..., 2]), np.sin(poses[..., 2])
    heading = batch.wrap_angle(reference[..., 2] - poses[..., 2])
    return np.stack([c * dx + s * dy, -s * dx + c * dy, heading], axis=-1)


def _poses(poses: object) -> np.ndarray:
    array = np.asarray(poses, dtype=float)
    if array.ndim != 2 or array.shape[1] != 3:
        raise ValueError(f"poses must be (N, 3) [x, y, theta], got shape {array.shape}")
    return array


@dataclass(frozen=True)
class Ramsete:
    """Ramsete with ``b`` (rad^2/m^2, > 0) and ``zeta`` (0 < zeta < 1); WPILib's defaults."""

    b: float = 2.0
    zeta: float = 0.7

    def __post_init__(self) -> None:
        positive("b", self.b)
        if not 0.0 < finite("zeta", self.zeta) < 1.0:
            raise ValueError(f"zeta must be in (0, 1), got {self.zeta!r}")

    def command(self, plan: Plan, t: float, poses: np.ndarray) -> np.ndarray:
        """``Tracker.command``: twists ``(N, 2)`` for ``poses`` ``(N, 3)`` at ``t`` s."""
        poses = _poses(poses)
        ref = plan.sample(t)
        v_r, w_r = ref["twist"]
        e = errors_in_robot(poses, ref["pose"])
        k = 2.0 * self.zeta * math.sqrt(w_r * w_r + self.b * v_r * v_r)
        sinc = np.sinc(e[:, 2] / np.pi)
        v = v_r * np.cos(e[:, 2]) + k * e[:, 0]
        omega = w_r + k * e[:, 2] + self.b * v_r * sinc * e[:, 1]
        return np.column_stack([v, omega])


class LTVUnicycle:
    """The LTV unicycle LQR (see the module): ``q`` (m, m, rad) and ``r`` (m/s, rad/s) the
    largest errors and efforts wanted (WPILib's defaults), ``dt`` (s) the control period,
    gains tabulated for speeds in ``[-max_velocity, max_velocity]`` (m/s)."""

    def __init__(
        self,
        q: tuple[float, float, float] = (0.0625, 0.125, 2.0),
        r: tuple[float, float] = (1.0, 2.0),
        dt: float = 0.02,
        max_velocity: float = 9.0,
    ) -> None:
        solve_discrete_are = optional(
            "scipy.linalg", "control", "LTVUnicycle (the Riccati equation)"
        ).solve_discrete_are

        for name, values, size in (("q", q, 3), ("r", r, 2)):
            if len(values) != size or not all(v > 0 and math.isfinite(v) for v in values):
                raise ValueError(f"{name} must be {size} finite numbers > 0, got {values!r}")
        self.q, self.r, self.dt = tuple(q), tuple(r), positive("dt", dt)
        positive("max_velocity", max_velocity)
        Q = np.diag(1.0 / np.square(q))
        R = np.diag(1.0 / np.square(r))
        self.speeds = np.linspace(-max_velocity, max_velocity, 201)
        gains = []
        B = np.array([[1.0, 0.0], [0.0, 0.0], [0.0, 1.0]])
        for v in self.speeds:
            # At rest the sideways error cannot be controlled; a small speed keeps the
            # Riccati equation solvable, as WPILib does.
            speed = v if abs(v) > 1e-4 else 1e-4
            A = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, speed], [0.0, 0.0, 0.0]])
            Ad = np.eye(3) + A * dt  # A is nilpotent: exp(A dt) = I + A dt
            Bd = (np.eye(3) * dt + A * dt * dt / 2.0) @ B
            P = solve_discrete_are(Ad, Bd, Q, R)
            gains.append(np.linalg.solve(Bd.T @ P @ Bd + R, Bd.T @ P @ Ad))
        self.gains = np.array(gains)  # (speeds, 2, 3)

    def gain(self, v: float) -> np.ndarray:
        """``(2, 3)``: the gain at reference speed ``v`` (m/s), interpolated in the table."""
        v = float(np.clip(v, self.speeds[0], self.speeds[-1]))
        flat = self.gains.reshape(len(self.speeds), -1)
        return np.array([np.interp(v, self.speeds, column) for column in flat.T]).reshape(2, 3)

    def command(self, plan: Plan, t: float, poses: np.ndarray) -> np.ndarray:
        """``Tracker.command``: twists ``(N, 2)`` for ``poses`` ``(N, 3)`` at ``t`` s."""
        poses = _poses(poses)
        ref = plan.sample(t)
        e = errors_in_robot(poses, ref["pose"])
        return ref["twist"][None, :] + e @ self.gain(float(ref["twist"][0])).T


@dataclass(frozen=True)
class PurePursuit:
    """Regulated pure pursuit: the lookahead distance is ``lookahead_time`` times the reference
    speed within ``[min_lookahead, max_lookahead]`` (m); the speed is the plan's, cut in
    proportion where the pursuit's radius is under ``min_radius`` (m); a robot whose lookahead
    point lies more than ``rotate_threshold`` (rad) off its heading turns in place at
    ``rotate_speed`` (rad/s), and so does a robot at the goal once the plan has ended, onto the
    goal's heading. ``window`` (s): how far around ``t`` the closest point is
    sought."""

    lookahead_time: float = 1.5
    min_lookahead: float = 0.3
    max_lookahead: float = 0.9
    min_radius: float = 0.9
    rotate_threshold: float = 0.785
    rotate_speed: float = 1.0
    window: float = 2.0

    def __post_init__(self) -> None:
        for name in ("lookahead_time", "min_lookahead", "max_lookahead", "min_radius"):
            positive(name, getattr(self, name))
        for name in ("rotate_threshold", "rotate_speed", "window"):
            positive(name, getattr(self, name))
        if self.min_lookahead > self.max_lookahead:
            raise ValueError("min_lookahead must not exceed max_lookahead")

    def command(self, plan: Plan, t: float, poses: np.ndarray) -> np.ndarray:
        """``Tracker.command``: twists ``(N, 2)`` for ``poses`` ``(N, 3)`` at ``t`` s."""
        poses = _poses(poses)
        ref = plan.sample(t)
        v_r = float(ref["twist"][0])
        near = np.flatnonzero(np.abs(plan.times - t) <= self.window)
        if len(near) == 0:
            near = np.array([int(np.argmin(np.abs(plan.times - t)))])
        points = plan.poses[near, :2]
        gaps = np.hypot(*(points[None, :, :] - poses[:, None, :2]).transpose(2, 0, 1))
        closest = gaps.argmin(axis=1)
        reach = np.clip(abs(v_r) * self.lookahead_time, self.min_lookahead, self.max_lookahead)
        index = np.arange(len(near))[None, :]
        beyond = (index >= closest[:, None]) & (gaps >= reach)
        target = np.where(beyond.any(axis=1), beyond.argmax(axis=1), len(near) - 1)
        goal = plan.poses[near[target]]
        local = errors_in_robot(poses, goal)
        distance2 = np.maximum(local[:, 0] ** 2 + local[:, 1] ** 2, 1e-12)
        curvature = 2.0 * local[:, 1] / distance2
        sign = 1.0 if v_r >= 0.0 else -1.0
        with np.errstate(divide="ignore"):
            radius = np.where(curvature != 0.0, 1.0 / np.abs(curvature), np.inf)
        speed = v_r * np.minimum(1.0, radius / self.min_radius)
        omega = speed * curvature
        # The angle of the lookahead point off the direction of travel.
        off = np.arctan2(local[:, 1], sign * local[:, 0])
        # Not at the goal, where the lookahead point shrinks onto the robot.
        turn = (np.abs(off) > self.rotate_threshold) & (distance2 > (0.5 * self.min_lookahead) ** 2)
        speed = np.where(turn, 0.0, speed)
        omega = np.where(turn, np.sign(off) * sign * self.rotate_speed, omega)
        # At the goal, once the plan has ended: turn in place onto the goal's heading.
        done = (t >= plan.times[-1]) & (distance2 <= self.min_lookahead**2)
        heading = errors_in_robot(poses, plan.poses[-1])[:, 2]
        settle = np.clip(2.0 * heading, -self.rotate_speed, self.rotate_speed)
        speed = np.where(done, 0.0, speed)
        omega = np.where(done, settle, omega)
        if plan.lin[np.searchsorted(plan.times, t).clip(0, len(plan.times) - 1)] == 0.0:
            return ref["twist"][None, :] + np.zeros((len(poses), 2))  # a turn in place: follow it
        return np.column_stack([speed, omega])


class Predictive:
    """``tracker`` ahead of a known actuation ``delay`` (s, a whole number of ``dt``) and a
    first-order ``lag`` (s) of the twist, for robots commanded every ``dt`` s.

    Call ``command`` once per period, in time order; it remembers the commands it returned
    (they are what the robots will do next) and the lag's state they lead to. ``reset``
    forgets them.
    """

    def __init__(self, tracker: Tracker, delay: float, dt: float, lag: float = 0.0) -> None:
        self.tracker, self.dt = tracker, positive("Predictive dt", dt)
        delay, lag = nonnegative("Predictive delay", delay), nonnegative("Predictive lag", lag)
        steps = delay / self.dt
        if not (math.isfinite(steps) and abs(steps - round(steps)) < 1e-9):
            raise ValueError(f"delay must be a whole number of dt ({dt} s) >= 0, got {delay!r}")
        self.delay, self.lag, self.steps = delay, lag, round(steps)
        self.reset()

    def reset(self) -> None:
        """Forget the commands sent: the robots at rest, nothing in flight; the next call
        sets how many robots there are."""
        self._sent = np.zeros((0, self.steps, 2))
        self._applied = np.zeros((0, 2))  # the twist the lag has reached

    def command(self, plan: Plan, t: float, poses: np.ndarray) -> np.ndarray:
        """``Tracker.command``: twists ``(N, 2)`` for ``poses`` ``(N, 3)`` at ``t`` s."""
        poses = _poses(poses)
        if len(self._applied) == 0:
            self._sent = np.zeros((len(poses), self.steps, 2))
            self._applied = np.zeros((len(poses), 2))
        elif len(poses) != len(self._applied):
            raise ValueError(
                f"expected {len(self._applied)} poses as before, got {len(poses)} (reset first)"
            )
        predicted, twist = poses.copy(), self._applied.copy()
        for k in range(self.steps):  # the commands in flight, in the order they take effect
            twist, mean = first_order(twist, self._sent[:, k], self.dt, self.lag)
            body = np.column_stack([mean[:, 0], np.zeros(len(mean)), mean[:, 1]])
            predicted = batch.integrate.step(predicted, body, self.dt)
        ahead = t + self.delay
        wanted = self.tracker.command(plan, ahead, predicted)
        # Lead the lag: the command whose lagged response follows the wanted twist.
        rate = plan.sample(ahead)["twist_rate"]
        command = wanted + self.lag * rate[None, :]
        oldest = self._sent[:, 0] if self.steps else command
        self._applied = first_order(self._applied, oldest, self.dt, self.lag)[0]
        if self.steps:
            self._sent = np.concatenate([self._sent[:, 1:], command[:, None]], axis=1)
        return command
