"""``PoseEstimator``: one streaming estimator for wheels, a gyro and late absolute poses.

Wheels. Every reading ``Odometry`` takes (counter ticks of any width, positions, increments,
velocities), through an ``Odometry`` kept inside, so that the same checks refuse the same
readings with the same messages; the estimator needs a time stamp ``t`` on each (late
measurements are placed by time).

Gyro. With each wheel reading, the angle the gyro turned since the last one (``gyro_angle``,
rad, bias included) or its rate at ``t`` (``gyro_rate``, rad/s, integrated by the trapezoid
rule; three IMU rates go through ``mounting``, the rotation from the IMU frame to the body).
``heading`` is ``"wheels"``, ``"gyro"`` or ``"fused"`` (``diffdrive.estimation.filter``); the
gyro bias is a state with ``"fused"``, and the turn scale (an effective track) one when
``turn_scale_sigma`` > 0. Every interval with a gyro reading is tested for slip as
``GyroOdometry`` did; a flagged interval's wheel turn is left out and its wheel noise inflated.

Absolute measurements. ``add_pose`` and ``add_position`` take a measurement stamped at its
own time ``t``: the estimator keeps the last ``history`` s of wheel intervals (each with the
state at its start), applies a measurement at its stamp (splitting the interval there) and
replays the intervals after it to now. So the result does not depend on the order in which
measurements arrive. A measurement is gated: past the ``gate`` probability's chi-square
quantile it is refused and counted (``rejected``). A stamp older than the history, or more
than ``ahead`` s past the newest wheel reading, raises ``ValueError``; one up to ``ahead`` s
past it waits for the wheels. ``pose_at(t)`` gives the pose and covariance at any stamp
inside the history.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, field

import numpy as np

from diffdrive._validate import finite, positive
from diffdrive.estimation import filter as ekf
from diffdrive.estimation.measurements import Measurement, _floats, chi2_quantile
from diffdrive.estimation.odometry import Odometry, offset_jacobian
from diffdrive.integrate import Method, check_method
from diffdrive.model import Robot, check_robot
from diffdrive.types import Pose, WheelVelocities

__all__ = ["HEADINGS", "GyroNoise", "PoseEstimator"]

HEADINGS: tuple[str, ...] = ("wheels", "gyro", "fused")


@dataclass(frozen=True)
class GyroNoise:
    """The gyro's noise: ``angle_random_walk`` (rad/s/sqrt(Hz)), ``rate_random_walk`` (the
    bias's random walk, rad/s/sqrt(s)) and ``initial_bias_sigma`` (rad/s, the prior on the
    bias). The defaults are those of a mid-range MEMS gyro."""

    angle_random_walk: float = 2e-3
    rate_random_walk: float = 1e-4
    initial_bias_sigma: float = 5e-3

    def __post_init__(self) -> None:
        for name in ("angle_random_walk", "rate_random_walk", "initial_bias_sigma"):
            value = finite(name, getattr(self, name))
            if not value >= 0.0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)!r}")
            if not math.isfinite(value * value):  # the filter works with its square
                raise ValueError(f"{name} {value!r} squares past the largest float")


@dataclass(eq=False)
class Interval:
    """One wheel interval ``(t0, t1]`` in the history: its data, the state and covariance at
    its start, the absolute measurements stamped inside it (in ``Measurement.order``), their
    outcomes and the slip test's."""

    t0: float
    t1: float
    wheels: tuple[float, float]
    gyro: float
    forced: bool
    start: tuple[np.ndarray, np.ndarray]
    measurements: list[Measurement] = field(default_factory=list)
    outcomes: list[tuple[bool, float]] = field(default_factory=list)
    slip: bool = False
    slip_score: float = 0.0
    steps: list[ekf.Step] = field(default_factory=list)


class PoseEstimator:
    """Wheels, gyro and absolute measurements in one extended Kalman filter (see the module).

    ``robot``: any model (its equivalent drive runs the filter; poses and covariances are
    the body origin's). ``heading``: ``"wheels"``, ``"gyro"`` or ``"fused"``.
    ``initial_pose`` and ``initial_covariance`` (3x3): the start; ``initial_time`` (s) its
    time, else the first ticks or positions reading's. ``ticks_per_revolution``,
    ``counter_bits``, ``max_wheel_speed``, ``method``: as ``Odometry``. ``k_left``, ``k_right``
    (m): the wheel noise. ``noise``: the gyro's (``GyroNoise``); ``bias`` (rad/s) its start.
    ``turn_scale`` and ``turn_scale_sigma``: the turn scale's start and prior standard
    deviation (0: not estimated). ``history`` (s, at least 2 by default): how far back a
    measurement may be stamped; ``ahead`` (s): how far ahead of the wheels. ``gate``: the
    probability inside the chi-square gate. ``slip_threshold``, ``slip_inflation``,
    ``command_sigma`` (rad/s): the slip tests'.
    """

    def __init__(
        self,
        robot: Robot,
        heading: str = "fused",
        initial_pose: object = None,
        initial_covariance: object = None,
        *,
        initial_time: float | None = None,
        ticks_per_revolution: float | None = None,
        counter_bits: int | None = None,
        max_wheel_speed: float | None = None,
        method: Method = "exact",
        k_left: float = 1e-4,
        k_right: float = 1e-4,
        noise: GyroNoise | None = None,
        bias: float = 0.0,
        turn_scale: float = 1.0,
        turn_scale_sigma: float = 0.0,
        mounting: object = None,
        history: float = 2.0,
        ahead: float = 0.1,
        gate: float = 0.999,
        slip_threshold: float = ekf.SLIP_THRESHOLD,
        slip_inflation: float = 100.0,
        command_sigma: float = 1.0,
    ) -> None:
        check_robot(robot)
        if heading not in HEADINGS:
            raise ValueError(f"heading must be one of {', '.join(HEADINGS)}, got {heading!r}")
        if noise is not None and not isinstance(noise, GyroNoise):
            raise TypeError(f"noise must be a GyroNoise, got {type(noise).__name__}")
        for name, value in (("k_left", k_left), ("k_right", k_right)):
            if not finite(name, value) >= 0.0:
                raise ValueError(f"{name} must be >= 0, got {value!r}")
        if not finite("turn_scale_sigma", turn_scale_sigma) >= 0.0:
            raise ValueError(f"turn_scale_sigma must be >= 0, got {turn_scale_sigma!r}")
        if not 0.0 < finite("gate", gate) < 1.0:
            raise ValueError(f"gate must be a probability in (0, 1), got {gate!r}")
        if not finite("ahead", ahead) >= 0.0:
            raise ValueError(f"ahead must be >= 0 s, got {ahead!r}")
        self.command_sigma = positive("command_sigma", command_sigma)
        if not 0.0 < self.command_sigma * self.command_sigma < math.inf:
            raise ValueError(f"command_sigma {command_sigma!r} squares to 0 or past the floats")
        self.robot, self.heading = robot, heading
        self.noise = GyroNoise() if noise is None else noise
        self.history = math.inf if history == math.inf else positive("history", history)
        self.ahead = float(ahead)
        self._mounting = mounting_yaw_row(mounting)
        drive = robot.equivalent
        self._offset = robot.reference_offset
        arw, rrw = self.noise.angle_random_walk, self.noise.rate_random_walk
        self.config = ekf.Config(
            (
                drive.left_wheel_radius,
                drive.right_wheel_radius,
                drive.track_width,
                drive.axle_offset,
            ),
            check_method(method),
            heading,
            (float(k_left), float(k_right)),
            arw * arw,
            rrw * rrw,
            heading == "fused",
            turn_scale_sigma > 0.0,
            positive("slip_threshold", slip_threshold),
            positive("slip_inflation", slip_inflation),
        )
        self._gate = {dof: chi2_quantile(gate, dof) for dof in (1, 2, 3)}
        self._wheels = Odometry(
            robot,
            method,
            ticks_per_revolution=ticks_per_revolution,
            counter_bits=counter_bits,
            max_wheel_speed=max_wheel_speed,
        )
        if initial_time is not None:
            self._wheels.update_increments(0.0, 0.0, finite("initial_time", initial_time))
        x, P = _start_state(
            robot,
            initial_pose,
            initial_covariance,
            finite("bias", bias),
            positive("turn_scale", turn_scale),
        )
        P[ekf.BIAS, ekf.BIAS] = self.noise.initial_bias_sigma**2 if heading == "fused" else 0.0
        P[ekf.SCALE, ekf.SCALE] = turn_scale_sigma * turn_scale_sigma
        self._state, self._P = x, P
        self._intervals: list[Interval] = []
        self._pending: list[Measurement] = []
        self._rate: float | None = None
        self._settled = [0, 0]  # accepted, rejected: measurements that left the history
        self.slip, self.slip_score, self.command_score = False, 0.0, 0.0
        self._smoother = False  # keep each interval's smoother steps (estimate_trajectory)

    # -- what it knows --------------------------------------------------------------------

    @property
    def time(self) -> float | None:
        """The time of the newest wheel reading, s; None before the first."""
        return self._wheels.time

    @property
    def state(self) -> np.ndarray:
        """``(x, y, theta, bias, turn_scale)`` of the equivalent drive's reference point."""
        return self._state.copy()

    @property
    def state_covariance(self) -> np.ndarray:
        """The state's covariance, 5x5."""
        return self._P.copy()

    @property
    def pose(self) -> Pose:
        """The body origin's pose now."""
        return _body_pose(self._state, self._offset)

    @property
    def covariance(self) -> np.ndarray:
        """The body origin's pose covariance now, 3x3 over ``(x, y, theta)``."""
        return _body_covariance(self._state, self._P, self._offset)

    @property
    def bias(self) -> float:
        """The gyro bias estimate, rad/s."""
        return float(self._state[ekf.BIAS])

    @property
    def turn_scale(self) -> float:
        """The turn scale estimate: the robot's turn per radian of the wheels' turn."""
        return float(self._state[ekf.SCALE])

    @property
    def accepted(self) -> int:
        """Absolute measurements taken (as the history now stands)."""
        return self._settled[0] + sum(ok for i in self._intervals for ok, _ in i.outcomes)

    @property
    def rejected(self) -> int:
        """Absolute measurements the gate refused (as the history now stands)."""
        return self._settled[1] + sum(not ok for i in self._intervals for ok, _ in i.outcomes)

    @property
    def history_start(self) -> float | None:
        """The oldest stamp a measurement may have now, s."""
        if self._intervals:
            return self._intervals[0].t0
        return self.time

    def pose_at(self, t: float) -> tuple[Pose, np.ndarray]:
        """The body origin's pose and 3x3 covariance at stamp ``t`` (s) inside the history,
        with every measurement stamped up to ``t``."""
        t = finite("t", t)
        start = self.history_start
        if start is None or not start <= t <= self.time:  # type: ignore[operator]
            raise ValueError(f"t = {t!r} s lies outside the history [{start!r}, {self.time!r}] s")
        k = bisect.bisect_left(self._intervals, t, key=_end)
        if k == len(self._intervals):
            x, P = self._state, self._P
        else:
            x, P = self._run(self._intervals[k], stop=t)
        return _body_pose(x, self._offset), _body_covariance(x, P, self._offset)

    # -- wheel readings ---------------------------------------------------------------------

    def update_ticks(self, left, right, t, *, gyro_angle=None, gyro_rate=None, commanded=None):
        """Absolute encoder counter readings at ``t`` s (the first sets the reference)."""
        self._update("update_ticks", (left, right, t), t, gyro_angle, gyro_rate, commanded)

    def update_positions(self, left, right, t, *, gyro_angle=None, gyro_rate=None, commanded=None):
        """Accumulated wheel angles (rad) at ``t`` s (the first sets the reference)."""
        self._update("update_positions", (left, right, t), t, gyro_angle, gyro_rate, commanded)

    def update_increments(self, left, right, t, *, gyro_angle=None, gyro_rate=None, commanded=None):
        """Wheel-angle increments (rad) since the last reading, at ``t`` s."""
        self._update("update_increments", (left, right, t), t, gyro_angle, gyro_rate, commanded)

    def update_velocities(
        self, left, right, dt, *, gyro_angle=None, gyro_rate=None, commanded=None
    ):
        """Wheel velocities (rad/s) held over ``dt`` s."""
        now = self.time if self.time is not None else 0.0
        t = now + positive("dt", dt)
        self._update("update_velocities", (left, right, dt), t, gyro_angle, gyro_rate, commanded)

    def _update(self, name, args, t, gyro_angle, gyro_rate, commanded) -> None:
        if t is None:
            raise ValueError(
                f"{name}: PoseEstimator needs the time t (s) of every reading: late "
                "measurements are placed by time"
            )
        before, previous = self._wheels._wheel_arcs(), self.time
        if previous is None and name == "update_increments":
            raise ValueError(
                f"{name}: the estimator's clock has not started: give initial_time, or "
                "begin with a ticks or positions reading"
            )
        if previous is None and name == "update_velocities":
            previous = 0.0  # velocities start the clock at 0 s, as Odometry's do
        # Everything about this reading is checked before anything changes: the gyro and
        # commands here, the wheels by their own update, which is all or nothing.
        rate = None if gyro_rate is None else self._gyro_rate(gyro_rate)
        if gyro_angle is not None:
            gyro_angle = finite("gyro_angle", gyro_angle)
        no_gyro = gyro_angle is None and rate is None
        if previous is not None and no_gyro and self.heading != "wheels":
            raise ValueError(
                f"{name}: heading {self.heading!r} needs gyro_angle or gyro_rate with every "
                "wheel reading"
            )
        wanted = None if commanded is None else WheelVelocities.coerce(commanded, "commanded")
        snapshot = self._wheels._snapshot()
        getattr(self._wheels, name)(*args)
        now: float = self._wheels.time  # type: ignore[assignment]  # every reading has a t
        if previous is None:  # a reference reading: the clock starts
            self._rate = rate
            return
        dt = now - previous
        after = self._wheels._wheel_arcs()
        r_l, r_r = self.config.drive[0], self.config.drive[1]
        dl, dr = (after[0] - before[0]) / r_l, (after[1] - before[1]) / r_r
        gyro = self._gyro_angle(gyro_angle, rate, dt)
        command_score = 0.0
        if wanted is not None and dt > 0.0:
            miss = (dl / dt - wanted.left, dr / dt - wanted.right)
            sigma2 = self.command_sigma * self.command_sigma
            command_score = (miss[0] * miss[0] + miss[1] * miss[1]) / sigma2
        forced = command_score > ekf.COMMAND_THRESHOLD
        interval = Interval(previous, now, (dl, dr), gyro, forced, (self._state, self._P))
        due = [m for m in self._pending if m.t <= now]
        interval.measurements = sorted(due, key=lambda m: m.order)
        try:
            with np.errstate(over="ignore", invalid="ignore", under="ignore"):
                x, P = self._run(interval)
            finite_state = bool(np.all(np.isfinite(x)) and np.all(np.isfinite(P)))
        except (ValueError, OverflowError, np.linalg.LinAlgError):  # math on an inf
            finite_state = False
        if not finite_state:
            self._wheels._restore(snapshot)
            raise ValueError(
                f"{name}: the update would overflow the state; refused, nothing changed"
            )
        self._pending = [m for m in self._pending if m.t > now]
        self.command_score = command_score
        self._rate = rate if rate is not None else self._rate
        self._intervals.append(interval)
        self._state, self._P = x, P
        self.slip, self.slip_score = interval.slip, interval.slip_score
        self._trim()

    def _gyro_rate(self, rate: object) -> float:
        if isinstance(rate, int | float):
            return finite("gyro_rate", rate)
        values = _floats(rate, "gyro_rate", "gyro_rate")
        if values.shape == (3,):
            values = np.asarray(self._mounting @ values)
        if values.shape != () or not np.isfinite(values):
            raise ValueError(f"gyro_rate must be a finite yaw rate or 3 IMU rates, got {rate!r}")
        return float(values)

    def _gyro_angle(self, angle: float | None, rate: float | None, dt: float) -> float:
        """The angle the gyro turned over the interval (NaN: no gyro)."""
        if angle is not None:
            return angle
        if rate is not None:
            held = rate if self._rate is None else self._rate
            return 0.5 * (held + rate) * dt
        return math.nan

    # -- absolute measurements ------------------------------------------------------------

    def add_pose(self, t, pose, covariance, lever_arm=None) -> bool:
        """A pose ``(x, y, theta)`` (m, m, rad) measured at stamp ``t`` (s), ``covariance`` 3x3
        or 3 standard deviations; True if the gate took it (False also while it waits for
        the wheels)."""
        return self._add(Measurement.make("pose", t, pose, covariance, lever_arm))

    def add_position(self, t, position, covariance, lever_arm=None) -> bool:
        """A position ``(x, y)`` (m) measured at stamp ``t`` (s), ``covariance`` 2x2, 2 or 1
        standard deviations; True if the gate took it."""
        return self._add(Measurement.make("position", t, position, covariance, lever_arm))

    def add_heading(self, t, heading, sigma) -> bool:
        """A heading (rad) measured at stamp ``t`` (s) with standard deviation ``sigma``
        (rad); True if the gate took it."""
        return self._add(Measurement.make("heading", t, [heading], sigma))

    def add(self, measurement: Measurement) -> bool:
        """A ``Measurement`` made elsewhere (``Measurement.make``)."""
        if not isinstance(measurement, Measurement):
            raise TypeError(f"measurement must be a Measurement, got {type(measurement).__name__}")
        return self._add(measurement)

    def _add(self, m: Measurement) -> bool:
        where = f"{m.kind} measurement at t = {m.t!r} s"
        now, start = self.time, self.history_start
        if now is None:
            raise ValueError(f"{where}: no wheel reading yet, so no time to place it at")
        if m.t > now + self.ahead:
            raise ValueError(
                f"{where}: more than ahead = {self.ahead!r} s past the newest wheel reading "
                f"({now!r} s)"
            )
        if m.t > now:
            self._pending.append(m)
            return False
        if not self._intervals or m.t < start:  # type: ignore[operator]
            if m.t == now and not self._intervals:  # at the start itself
                with np.errstate(all="ignore"):
                    x, P, ok, _ = ekf.absolute_update(
                        self._state, self._P, m, self._offset, self._gate
                    )
                if not (np.all(np.isfinite(x)) and np.all(np.isfinite(P))):
                    raise ValueError(f"{where}: it would overflow the state; refused")
                self._state, self._P = x, P
                self._settled[0 if ok else 1] += 1
                return ok
            raise ValueError(
                f"{where}: older than the history, which starts at {start!r} s "
                f"(history = {self.history!r} s)"
            )
        k = bisect.bisect_left(self._intervals, m.t, key=_end)
        target = self._intervals[k]
        kept = [
            (i.start, list(i.measurements), i.outcomes, i.steps, i.slip, i.slip_score)
            for i in self._intervals[k:]
        ]
        keys = [x.order for x in target.measurements]
        target.measurements.insert(bisect.bisect_right(keys, m.order), m)
        try:
            with np.errstate(all="ignore"):
                x, P = self._replay(k)
            finite_state = bool(np.all(np.isfinite(x)) and np.all(np.isfinite(P)))
        except (ValueError, OverflowError, np.linalg.LinAlgError):
            finite_state = False
        if not finite_state:  # the history as it was
            for interval, old in zip(self._intervals[k:], kept, strict=True):
                (interval.start, interval.measurements, interval.outcomes, interval.steps) = old[:4]
                interval.slip, interval.slip_score = old[4:]
            raise ValueError(f"{where}: it would overflow the state; refused, nothing changed")
        self._state, self._P = x, P
        return target.outcomes[target.measurements.index(m)][0]

    # -- the history ----------------------------------------------------------------------

    def _run(self, interval: Interval, stop: float | None = None):
        """Run ``interval`` from its start state (splitting it at each measurement's stamp)
        and record its outcomes (and its smoother steps, if kept); with ``stop``, only up to
        that time, recording nothing."""
        c = self.config
        x, P = interval.start
        (dl, dr), g, duration = interval.wheels, interval.gyro, interval.t1 - interval.t0
        if stop is None:
            if math.isnan(g):
                interval.slip, interval.slip_score = interval.forced, 0.0
            else:
                score = ekf.slip_score(c, x, P, dl, dr, g, duration)
                interval.slip = bool(score > c.slip_threshold) or interval.forced
                interval.slip_score = float(score)
        end = interval.t1 if stop is None else stop
        cuts = sorted({m.t for m in interval.measurements if m.t <= end} | {end})
        outcomes: list[tuple[bool, float]] = []
        done, t = 0.0, interval.t0
        queue = list(interval.measurements)
        sink: list[ekf.Step] | None = [] if self._smoother and stop is None else None
        keep = sink is not None
        for cut in cuts:
            share = (cut - interval.t0) / duration if duration > 0.0 else 1.0
            part = share - done
            if cut > t:
                x, P, step = ekf.advance(
                    c, x, P, part * dl, part * dr, part * g, cut - t, interval.slip, keep
                )
                if sink is not None and step is not None:
                    sink.append(step)
            done, t = share, cut
            while queue and queue[0].t <= cut:
                m = queue.pop(0)
                x, P, ok, score = ekf.absolute_update(x, P, m, self._offset, self._gate)
                outcomes.append((ok, score))
        if stop is None:
            interval.outcomes = outcomes
            interval.steps = sink or []
        return x, P

    def _replay(self, first: int) -> tuple[np.ndarray, np.ndarray]:
        """Run the intervals from ``first`` on, each from the end of the one before: the
        state and covariance now."""
        x, P = self._intervals[first].start
        for interval in self._intervals[first:]:
            interval.start = (x, P)
            x, P = self._run(interval)
        return x, P

    def _trim(self) -> None:
        newest = self._intervals[-1].t1
        while len(self._intervals) > 1 and self._intervals[1].t0 < newest - self.history:
            gone = self._intervals.pop(0)
            for ok, _ in gone.outcomes:
                self._settled[0 if ok else 1] += 1


def _end(interval: Interval) -> float:
    return interval.t1


def mounting_yaw_row(mounting: object) -> np.ndarray:
    """The row of ``mounting`` (3x3, IMU frame to body frame; None: the identity) that turns
    an IMU's three rates into the body's yaw rate; ``ValueError`` unless it is a rotation."""
    rotation = np.eye(3) if mounting is None else np.asarray(mounting, dtype=float)
    if rotation.shape != (3, 3) or not np.all(np.isfinite(rotation)):
        raise ValueError(f"mounting must be a finite 3x3 rotation, got shape {rotation.shape}")
    if not (
        np.allclose(rotation @ rotation.T, np.eye(3), atol=1e-6) and np.linalg.det(rotation) > 0
    ):
        raise ValueError("mounting is not a rotation (orthonormal, determinant +1)")
    return rotation[2].copy()


def _start_state(robot: Robot, pose: object, covariance: object, bias: float, scale: float):
    start = Pose() if pose is None else Pose.coerce(pose, "initial_pose")
    matrix = np.zeros((3, 3)) if covariance is None else np.asarray(covariance, dtype=float)
    if matrix.shape != (3, 3) or not np.all(np.isfinite(matrix)):
        raise ValueError(f"initial_covariance must be a finite 3x3, got shape {matrix.shape}")
    if not np.allclose(matrix, matrix.T) or np.linalg.eigvalsh(matrix).min() < -1e-12 * max(
        1.0, np.abs(matrix).max()
    ):
        raise ValueError("initial_covariance must be symmetric positive semi-definite")
    offset = robot.reference_offset
    moved = offset_jacobian(start.theta, offset)
    start = start.compose(Pose(0.0, offset))
    P = np.zeros((ekf.N, ekf.N))
    P[:3, :3] = moved @ matrix @ moved.T
    return np.array([start.x, start.y, start.theta, bias, scale]), P


def _body_pose(x: np.ndarray, offset: float) -> Pose:
    pose = Pose(float(x[0]), float(x[1]), float(x[2]))
    return pose.compose(Pose(0.0, -offset)) if offset else pose


def _body_covariance(x: np.ndarray, P: np.ndarray, offset: float) -> np.ndarray:
    if not offset:
        return P[:3, :3].copy()
    moved = offset_jacobian(x[2], -offset)
    return moved @ P[:3, :3] @ moved.T
