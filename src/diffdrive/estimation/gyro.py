"""Gyro-aided odometry and slip detection.

Real robots slip, and carry a gyro. ``GyroOdometry`` takes, for each interval between two wheel
readings, the wheels' travel and the angle the gyro turned, and keeps the pose with one of three
heading sources:

- ``"wheels"``: the heading from the wheels, as ``Odometry`` (the gyro only watches for slip);
- ``"gyro"``: the heading from the gyro less a fixed bias, the translation from the wheels (as
  WPILib's odometry takes its heading from the gyro);
- ``"fused"``: an extended Kalman filter on ``(x, y, theta, gyro bias)``. The gyro drives the
  heading; each interval's wheel heading change is a measurement of it (the filter keeps a copy
  of the heading at the interval's start, "stochastic cloning", Roumeliotis and Burdick, ICRA
  2002), which also makes the bias observable. Its covariance is the pose covariance.

Noise models. Gyro (IEEE Std 952-1997 terms): white rate noise of ``angle_random_walk``
rad/s/sqrt(Hz), so an interval of ``dt`` s adds ``arw^2 dt`` rad^2 to the heading; a bias that
random-walks by ``rate_random_walk`` rad/s/sqrt(s). Wheels (Siegwart, Nourbakhsh and
Scaramuzza, 2011, sec. 5.2.4, as ``Odometry``): each wheel's travel has variance ``k |travel|``,
so the forward travel has variance ``(k_l |s_l| + k_r |s_r|) / 4`` and the wheels' heading change
``(k_l |s_l| + k_r |s_r|) / track^2``.

Slip. Every interval, the wheels' heading change is compared with the gyro's (less the bias):
the innovation squared over its variance is chi-square with one degree of freedom when neither
slips. Past ``slip_threshold`` (default 10.83, a false-alarm probability of 0.1 %) the interval
is flagged: its wheel heading is left out of the fused estimate and its forward-travel variance
is multiplied by ``slip_inflation``. Where the log also has the commanded wheel velocities,
each interval's measured wheel velocities are compared with them as well: the sum of both
wheels' squared differences over ``command_sigma^2`` (rad/s, how closely the drives follow
their commands) is chi-square with two degrees of freedom, flagged past 13.82 (0.1 %): a wheel
that spins up far beyond its command has lost the ground. Flags and scores are kept for every
interval.

The gyro's yaw rate is in the body frame: ``Gyro.from_imu`` rotates an IMU's three rates by the
mounting rotation (IMU frame to body frame), which must be a rotation; ``Gyro.from_yaw`` takes a
yaw angle instead. ``gyro_odometry`` runs a whole log, the gyro's own samples integrated over
each wheel interval; the bias, unless given, is the gyro's mean rate while the wheels stand
still.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from diffdrive._step import Method, check_method, method_flags, move_jacobians, wheel_move
from diffdrive._validate import finite, positive
from diffdrive.estimation.odometry import offset_jacobian
from diffdrive.model import Robot, check_robot
from diffdrive.types import Pose, WheelVelocities

__all__ = [
    "HEADINGS",
    "Gyro",
    "GyroNoise",
    "GyroOdometry",
    "GyroTrajectory",
    "gyro_odometry",
    "rotation_from_rpy",
]

Heading = Literal["wheels", "gyro", "fused"]
HEADINGS: tuple[Heading, ...] = ("wheels", "gyro", "fused")
# chi-square, one degree of freedom: P(score > 10.83) = 0.001.
SLIP_THRESHOLD = 10.83
# chi-square, two degrees of freedom (both wheels): P(score > 13.82) = 0.001.
COMMAND_THRESHOLD = 13.82


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


def rotation_from_rpy(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """The rotation ``Rz(yaw) Ry(pitch) Rx(roll)`` (rad), e.g. an IMU's mounting in the body."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


@dataclass(frozen=True, eq=False)
class Gyro:
    """Body yaw rates ``rates`` ``(M,)`` rad/s at strictly increasing ``times`` ``(M,)`` s,
    linear in between. ``max_gap`` (s) is the longest the stream may fall silent. ``yaw``
    ``(M,)`` rad, unwrapped, is set by ``from_yaw``: the angles are then the yaw's own, exact at
    its stamps and linear between them (each interval's rate held)."""

    times: np.ndarray
    rates: np.ndarray
    max_gap: float = field(default=math.inf)
    yaw: np.ndarray | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        gap = math.inf if self.max_gap == math.inf else positive("max_gap", self.max_gap)
        times = np.asarray(self.times, dtype=float)
        rates = np.asarray(self.rates, dtype=float)
        if times.ndim != 1 or rates.shape != times.shape or len(times) < 2:
            raise ValueError(
                f"gyro times and rates must be (M,) with M >= 2, got {times.shape} "
                f"and {rates.shape}"
            )
        if not np.all(np.isfinite(times)):
            raise ValueError("gyro times and rates must be finite")
        steps = np.diff(times)
        if np.any(steps <= 0):
            k = int(np.argmax(steps <= 0)) + 1
            raise ValueError(f"gyro times must increase: {times[k]:g} after {times[k - 1]:g}")
        if not np.all(np.isfinite(rates)):
            raise ValueError("gyro times and rates must be finite")
        if np.any(steps > gap):
            k = int(np.argmax(steps > gap))
            raise ValueError(
                f"the gyro stream stops for {steps[k]:.3g} s after t = "
                f"{times[k]:g} s (max_gap {self.max_gap:g} s)"
            )
        if self.yaw is not None:
            yaw = np.asarray(self.yaw, dtype=float)
            if yaw.shape != times.shape or not np.all(np.isfinite(yaw)):
                raise ValueError(f"gyro yaw must be finite and {times.shape}, got {yaw.shape}")
            object.__setattr__(self, "yaw", yaw)
        object.__setattr__(self, "times", times)
        object.__setattr__(self, "rates", rates)
        object.__setattr__(self, "max_gap", gap)

    @classmethod
    def from_imu(cls, times, angular_velocity, mounting=None, max_gap: float = math.inf) -> Gyro:
        """From an IMU's rates ``(M, 3)`` in its own frame and ``mounting``, the 3x3 rotation
        from the IMU frame to the body frame (default: the identity, z up)."""
        rotation = np.eye(3) if mounting is None else np.asarray(mounting, dtype=float)
        if rotation.shape != (3, 3) or not np.all(np.isfinite(rotation)):
            raise ValueError(f"mounting must be a finite 3x3 rotation, got shape {rotation.shape}")
        if not (
            np.allclose(rotation @ rotation.T, np.eye(3), atol=1e-6) and np.linalg.det(rotation) > 0
        ):
            raise ValueError("mounting is not a rotation (orthonormal, determinant +1)")
        rates = np.asarray(angular_velocity, dtype=float)
        if rates.ndim != 2 or rates.shape[1] != 3:
            raise ValueError(f"angular_velocity must be (M, 3), got {rates.shape}")
        return cls(times, rates @ rotation[2], max_gap)

    @classmethod
    def from_yaw(cls, times, yaw, max_gap: float = math.inf) -> Gyro:
        """From yaw angles ``(M,)`` rad (unwrapped here): ``angles`` gives the yaw back at its
        own stamps, and between them the rate of each interval, held."""
        times, yaw = np.asarray(times, dtype=float), np.asarray(yaw, dtype=float)
        if yaw.ndim != 1 or yaw.shape != times.shape or len(yaw) < 2:
            raise ValueError(
                f"gyro times and yaw must be (M,) with M >= 2, got {times.shape} and {yaw.shape}"
            )
        if not np.all(np.isfinite(yaw)):
            raise ValueError("gyro yaw must be finite")
        yaw = np.unwrap(yaw)
        with np.errstate(divide="ignore", invalid="ignore"):  # times are checked when built
            rates = np.diff(yaw) / np.diff(times)
        return cls(times, np.concatenate([rates, rates[-1:]]), max_gap, yaw)

    def angles(self, at: np.ndarray) -> np.ndarray:
        """The angle turned (rad) from ``times[0]`` to each time ``at`` ``(N,)``, the rate linear
        between samples; every time must lie within the gyro's span."""
        at = np.asarray(at, dtype=float)
        if at.size == 0:
            return np.zeros(at.shape)
        if at.min() < self.times[0] or at.max() > self.times[-1]:
            raise ValueError(
                f"the wheel log spans [{at.min():g}, {at.max():g}] s, the gyro only "
                f"[{self.times[0]:g}, {self.times[-1]:g}] s"
            )
        if self.yaw is not None:  # the yaw itself: exact at its stamps, linear between
            return np.interp(at, self.times, self.yaw) - self.yaw[0]
        steps = np.diff(self.times)
        cumulative = np.concatenate(
            [[0.0], np.cumsum(0.5 * (self.rates[1:] + self.rates[:-1]) * steps)]
        )
        k = np.clip(np.searchsorted(self.times, at, side="right") - 1, 0, len(steps) - 1)
        into = at - self.times[k]
        slope = (self.rates[k + 1] - self.rates[k]) / steps[k]
        return cumulative[k] + self.rates[k] * into + 0.5 * slope * into**2


class GyroOdometry:
    """Dead reckoning with a gyro, one interval at a time (see the module).

    ``robot`` gives the geometry (any model: the filter runs its equivalent drive, at its
    reference point, and moves poses and covariances back to the body origin); ``heading`` is
    ``"wheels"``, ``"gyro"`` or ``"fused"``; ``bias`` (rad/s) is the gyro's, fixed for
    ``"gyro"`` and the prior mean for ``"fused"``; ``k_left``, ``k_right`` (m) the wheel
    model; ``noise`` the gyro's; ``method`` the step's (``"exact"``, ``"rk2"``, ``"euler"``).
    """

    def __init__(
        self,
        robot: Robot,
        heading: Heading = "fused",
        initial_pose: Pose | None = None,
        *,
        bias: float = 0.0,
        noise: GyroNoise | None = None,
        k_left: float = 1e-4,
        k_right: float = 1e-4,
        slip_threshold: float = SLIP_THRESHOLD,
        slip_inflation: float = 100.0,
        command_sigma: float = 1.0,
        method: Method = "exact",
    ) -> None:
        check_robot(robot)
        if noise is not None and not isinstance(noise, GyroNoise):
            raise TypeError(f"noise must be a GyroNoise, got {type(noise).__name__}")
        if heading not in HEADINGS:
            raise ValueError(f"heading must be one of {', '.join(HEADINGS)}, got {heading!r}")
        for name, value in (("k_left", k_left), ("k_right", k_right)):
            if not finite(name, value) >= 0.0:
                raise ValueError(f"{name} must be >= 0, got {value!r}")
        self.robot, self.heading, self.method = robot, heading, check_method(method)
        self.noise = GyroNoise() if noise is None else noise
        self.k = (float(k_left), float(k_right))
        self.slip_threshold = positive("slip_threshold", slip_threshold)
        self.slip_inflation = positive("slip_inflation", slip_inflation)
        self.command_sigma = positive("command_sigma", command_sigma)
        if not 0.0 < self.command_sigma * self.command_sigma < math.inf:
            raise ValueError(f"command_sigma {command_sigma!r} squares to 0 or past the floats")
        pose = Pose() if initial_pose is None else Pose.coerce(initial_pose, "initial_pose")
        self._offset = robot.reference_offset
        pose = pose.compose(Pose(0.0, self._offset))  # to the equivalent drive's point
        # The state is the equivalent drive's: its reference point's pose, then the bias.
        self.state = np.array([pose.x, pose.y, pose.theta, finite("bias", bias)])
        self.covariance4 = np.diag([0.0, 0.0, 0.0, self.noise.initial_bias_sigma**2])
        self.slip = False
        self.slip_score = 0.0
        self.command_score = 0.0

    @property
    def pose(self) -> Pose:
        """The body origin's pose."""
        return Pose(*self.state[:3].tolist()).compose(Pose(0.0, -self._offset))

    @property
    def bias(self) -> float:
        """The gyro bias estimate, rad/s."""
        return float(self.state[3])

    @property
    def covariance(self) -> np.ndarray:
        """The body origin's pose covariance, 3x3 over ``(x, y, theta)``."""
        if not self._offset:
            return self.covariance4[:3, :3].copy()
        moved = offset_jacobian(self.state[2], -self._offset)
        return moved @ self.covariance4[:3, :3] @ moved.T

    def update(
        self,
        left: float,
        right: float,
        gyro_angle: float,
        dt: float,
        commanded: object = None,
    ) -> None:
        """One interval of ``dt`` s: wheel-angle increments ``left``, ``right`` (rad), the
        angle the gyro turned (rad, bias included) and, if known, the ``commanded`` wheel
        velocities ``(left, right)`` (rad/s). A refused update changes nothing."""
        left, right = finite("left", left), finite("right", right)
        gyro_angle, dt = finite("gyro_angle", gyro_angle), positive("dt", dt)
        command_score = 0.0
        if commanded is not None:
            wanted = WheelVelocities.coerce(commanded, "commanded")
            measured = (float(left) / dt - wanted.left, float(right) / dt - wanted.right)
            sigma = self.command_sigma
            command_score = (measured[0] * measured[0] + measured[1] * measured[1]) / (
                sigma * sigma
            )
        with np.errstate(over="ignore", invalid="ignore"):  # refused below, not warned about
            state, covariance, slip, score = _step(
                self, left, right, gyro_angle, dt, command_score > COMMAND_THRESHOLD
            )
        if not (np.all(np.isfinite(state)) and np.all(np.isfinite(covariance))):
            raise ValueError("the update would overflow the state; refused, nothing changed")
        self.state, self.covariance4, self.slip, self.slip_score = state, covariance, slip, score
        self.command_score = float(command_score)


def _jacobians(
    offset: float, state: np.ndarray, forward: float, turn: float, dt: float, method: Method
):
    """The next state after ``forward`` m and ``turn`` rad by the ``method``'s step (exact: the
    constant-curvature arc), d(next state)/d(state) (4x4, the bias turning the heading by
    ``-dt`` per rad/s) and d(next state)/d(forward, turn) (4x2)."""
    x, y, theta, bias = state
    dx, dy, by_forward, by_turn = move_jacobians(
        forward, offset, turn, *method_flags(method), heading=theta
    )
    by_state = np.eye(4)
    by_state[:2, 2] = -dy, dx
    by_state[:3, 3] = -dt * by_turn[0], -dt * by_turn[1], -dt
    by_input = np.array(
        [[by_forward[0], by_turn[0]], [by_forward[1], by_turn[1]], [0.0, 1.0], [0.0, 0.0]]
    )
    return np.array([x + dx, y + dy, theta + turn, bias]), by_state, by_input


def _step(o: GyroOdometry, left: float, right: float, gyro_angle: float, dt: float, forced: bool):
    """The next state and covariance, the slip flag and score of one interval of wheel-angle
    increments ``left``, ``right`` (rad)."""
    drive, noise, (k_l, k_r) = o.robot.equivalent, o.noise, o.k
    r_l, r_r, track = drive.left_wheel_radius, drive.right_wheel_radius, drive.track_width
    forward, _, wheel_turn = wheel_move(r_l, r_r, track, drive.axle_offset, left, right)
    spread = k_l * abs(r_l * left) + k_r * abs(r_r * right)
    # Products, not powers: a float's power raises where the product overflows to inf,
    # which the update then refuses with the state unchanged.
    forward_var, wheel_turn_var = spread / 4.0, spread / (track * track) + 1e-18
    gyro_var = noise.angle_random_walk * noise.angle_random_walk * dt
    gyro_turn = gyro_angle - o.state[3] * dt
    turn = wheel_turn if o.heading == "wheels" else gyro_turn
    turn_var = wheel_turn_var if o.heading == "wheels" else gyro_var
    moved, by_state, by_input = _jacobians(drive.axle_offset, o.state, forward, turn, dt, o.method)
    if o.heading == "wheels":
        by_state[:3, 3] = 0.0  # the bias plays no part in this heading
    bias_var = noise.rate_random_walk * noise.rate_random_walk * dt if o.heading == "fused" else 0.0
    previous = o.covariance4
    # The clone of the heading at the interval's start rides along as a fifth state.
    lift = np.vstack([by_state, [0.0, 0.0, 1.0, 0.0]])
    covariance = lift @ previous @ lift.T
    covariance[:4, :4] += by_input @ np.diag([forward_var, turn_var]) @ by_input.T
    covariance[3, 3] += bias_var
    # Slip: the wheels' heading change against the gyro's, chi-square with one dof.
    innovation = wheel_turn - gyro_turn
    gyro_side = gyro_var + dt * dt * previous[3, 3]
    score = innovation * innovation / (wheel_turn_var + gyro_side)
    slip = bool(score > o.slip_threshold) or forced
    state = moved
    if o.heading == "fused" and not slip:
        h = np.array([0.0, 0.0, 1.0, 0.0, -1.0])
        predicted = moved[2] - o.state[2]
        s = float(h @ covariance @ h) + wheel_turn_var
        gain = covariance @ h / s
        state = moved + gain[:4] * (wheel_turn - predicted)
        covariance = covariance - np.outer(gain, h @ covariance)
    if slip:
        covariance[:4, :4] += (
            (o.slip_inflation - 1.0) * forward_var * np.outer(by_input[:, 0], by_input[:, 0])
        )
    covariance = 0.5 * (covariance + covariance.T)
    return state, covariance[:4, :4], slip, float(score)


@dataclass(frozen=True, eq=False)
class GyroTrajectory:
    """``gyro_odometry``'s result: ``times`` ``(N,)``, ``poses`` ``(N, 3)``, ``covariances``
    ``(N, 3, 3)``, ``bias`` ``(N,)`` rad/s, and per row the ``slip`` flag and ``slip_score`` of
    the interval that ends there (False and 0 on the first row)."""

    times: np.ndarray
    poses: np.ndarray
    covariances: np.ndarray
    bias: np.ndarray
    slip: np.ndarray
    slip_score: np.ndarray
    heading: str


def gyro_odometry(
    robot: Robot,
    times: object,
    increments: object,
    gyro: Gyro,
    heading: Heading = "fused",
    initial_pose: object = None,
    *,
    bias: float | None = None,
    commanded: object = None,
    **options,
) -> GyroTrajectory:
    """A whole log: wheel-angle ``increments`` ``(N-1, 2)`` rad between ``times`` ``(N,)`` s,
    and the ``gyro``, integrated over each interval. ``bias`` (rad/s) defaults to the gyro's
    mean rate while the wheels stand still (refused for ``"gyro"`` when they never do; 0 for
    ``"fused"``, which estimates it). ``commanded`` ``(N-1, 2)`` rad/s, if given, are the
    wheel velocities commanded over each interval. ``options`` go to ``GyroOdometry``."""
    times = np.asarray(times, dtype=float)
    increments = np.asarray(increments, dtype=float)
    if times.ndim != 1:
        raise ValueError(f"times must be (N,) s, got shape {times.shape}")
    if not np.all(np.isfinite(times)) or np.any(np.diff(times) <= 0):
        raise ValueError("times must be finite and increase strictly")
    if increments.shape != (len(times) - 1, 2) or len(times) < 2:
        raise ValueError(
            f"increments must be (N-1, 2) for {len(times)} times, got {increments.shape}"
        )
    turned = np.diff(gyro.angles(times))
    if commanded is not None:
        commanded = np.asarray(commanded, dtype=float)
        if commanded.shape != increments.shape:
            raise ValueError(f"commanded must be {increments.shape}, got {commanded.shape}")
    if bias is None:
        bias = stationary_bias(times, increments, turned)
        if bias is None:
            if heading == "gyro":
                raise ValueError(
                    "heading 'gyro' needs the gyro bias: give it (bias=, --gyro-bias), or a "
                    "log in which the wheels stand still for a while"
                )
            bias = 0.0
    start = None if initial_pose is None else Pose.coerce(initial_pose, "initial_pose")
    odometry = GyroOdometry(robot, heading, start, bias=bias, **options)
    n = len(times)
    poses, covariances = np.empty((n, 3)), np.empty((n, 3, 3))
    biases, slips, scores = np.empty(n), np.zeros(n, dtype=bool), np.zeros(n)
    poses[0], covariances[0], biases[0] = (
        odometry.pose.to_array(),
        odometry.covariance,
        odometry.bias,
    )
    dts = np.diff(times)
    for k in range(1, n):
        try:
            odometry.update(
                increments[k - 1, 0],
                increments[k - 1, 1],
                turned[k - 1],
                dts[k - 1],
                None if commanded is None else commanded[k - 1],
            )
        except ValueError as exc:
            raise ValueError(
                f"interval {k - 1} ({times[k - 1]!r} to {times[k]!r} s): {exc}"
            ) from None
        poses[k], covariances[k] = odometry.pose.to_array(), odometry.covariance
        biases[k], slips[k], scores[k] = odometry.bias, odometry.slip, odometry.slip_score
    return GyroTrajectory(times, poses, covariances, biases, slips, scores, heading)


def stationary_bias(times, increments, turned, least: float = 0.5) -> float | None:
    """The gyro's mean rate (rad/s) over the intervals in which neither wheel turned, if they
    add up to ``least`` s or more; else None."""
    still = np.all(increments == 0.0, axis=1)
    duration = float(np.sum(np.diff(times)[still]))
    if duration < least:
        return None
    return float(np.sum(turned[still]) / duration)
