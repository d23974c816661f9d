"""Gyro streams and gyro-aided odometry of whole logs.

``Gyro`` holds a gyro's own samples (yaw rates, or a yaw angle) and integrates them over any
interval; ``Gyro.from_imu`` rotates an IMU's three rates by its mounting (IMU frame to body
frame, which must be a rotation), ``Gyro.from_yaw`` takes a yaw angle.

The filter is ``PoseEstimator`` (``diffdrive.estimation.fusion``: heading from the wheels, the
gyro or both, slip tests, noise models). ``gyro_odometry`` runs it over a whole log, the
gyro's own samples integrated over each wheel interval, and keeps what a slip study needs
per interval; the bias, unless given, is the gyro's mean rate while the wheels stand still.
``GyroOdometry`` is ``PoseEstimator`` behind the per-interval ``update`` it had before.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from diffdrive._validate import positive
from diffdrive.estimation.fusion import HEADINGS, GyroNoise, PoseEstimator, mounting_yaw_row
from diffdrive.model import Robot
from diffdrive.types import Pose

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
        yaw_row = mounting_yaw_row(mounting)
        rates = np.asarray(angular_velocity, dtype=float)
        if rates.ndim != 2 or rates.shape[1] != 3:
            raise ValueError(f"angular_velocity must be (M, 3), got {rates.shape}")
        return cls(times, rates @ yaw_row, max_gap)

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


class GyroOdometry(PoseEstimator):
    """``PoseEstimator`` behind the interface gyro-aided odometry had before it: one
    ``update`` per interval of ``dt`` s with the wheel-angle increments and the angle the gyro
    turned, its clock starting at 0 s. ``robot``, ``heading``, ``bias``, ``noise``, ``k_left``,
    ``k_right``, the slip options and ``method`` are ``PoseEstimator``'s."""

    def __init__(
        self,
        robot: Robot,
        heading: Heading = "fused",
        initial_pose: Pose | None = None,
        **options,
    ) -> None:
        super().__init__(robot, heading, initial_pose, initial_time=0.0, **options)

    @property
    def covariance4(self) -> np.ndarray:
        """The covariance of ``(x, y, theta, bias)`` of the reference point, 4x4."""
        return self.state_covariance[:4, :4]

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
        now = self.time
        t = now + positive("dt", dt)  # type: ignore[operator]
        if not math.isfinite(t):
            raise ValueError(f"dt {dt!r} s takes the clock past the largest float")
        self.update_increments(left, right, t, gyro_angle=gyro_angle, commanded=commanded)


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
    from diffdrive.estimation.smoother import estimate_trajectory

    estimate = estimate_trajectory(
        robot,
        times,
        increments,
        gyro=gyro,
        heading=heading,
        initial_pose=initial_pose,
        smooth=False,
        commanded=commanded,
        bias=bias,
        **options,
    )
    return GyroTrajectory(
        times,
        estimate.poses,
        estimate.covariances,
        estimate.states[:, 3],
        estimate.slip,
        estimate.slip_score,
        heading,
    )


def stationary_bias(times, increments, turned, least: float = 0.5) -> float | None:
    """The gyro's mean rate (rad/s) over the intervals in which neither wheel turned, if they
    add up to ``least`` s or more; else None."""
    still = np.all(increments == 0.0, axis=1)
    duration = float(np.sum(np.diff(times)[still]))
    if duration < least:
        return None
    return float(np.sum(turned[still]) / duration)
