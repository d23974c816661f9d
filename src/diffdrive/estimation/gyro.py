"""Gyro-aided odometry of whole logs, and the per-interval interface it had before.

The gyro's stream is ``diffdrive.estimation.imu``'s ``Gyro`` (kept importable from here, as
``rotation_from_rpy``). The filter is ``PoseEstimator`` (``diffdrive.estimation.fusion``:
heading from the wheels, the gyro or both, slip tests, noise models). ``gyro_odometry`` runs
it over a whole log, the gyro's own samples integrated over each wheel interval, and keeps
what a slip study needs per interval; the bias, unless given, is the gyro's mean rate while
the wheels stand still.
``GyroOdometry`` is ``PoseEstimator`` behind the per-interval ``update`` it had before.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from diffdrive._validate import positive, settings_of
from diffdrive.estimation.fusion import HEADINGS, GyroNoise, PoseEstimator
from diffdrive.estimation.imu import Gyro, rotation_from_rpy
from diffdrive.estimation.settings import EstimatorSettings
from diffdrive.estimation.smoother import calibrated_log, estimate_trajectory
from diffdrive.estimation.standing import identify_standing
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


class GyroOdometry(PoseEstimator):
    """``PoseEstimator`` behind the interface gyro-aided odometry had before it: one
    ``update`` per interval of ``dt`` s with the wheel-angle increments and the angle the gyro
    turned, its clock starting at 0 s. ``robot``, ``settings`` and ``initial_pose`` are
    ``PoseEstimator``'s."""

    def __init__(
        self,
        robot: Robot,
        settings: EstimatorSettings | None = None,
        *,
        initial_pose: Pose | None = None,
    ) -> None:
        super().__init__(robot, settings, initial_pose=initial_pose, initial_time=0.0)

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
    the interval that ends there (False and 0 on the first row); ``twists`` ``(N, 3)`` and
    ``twist_covariances`` ``(N, 3, 3)`` and ``settings`` (the gyro's noise and bias, and where
    from) as ``Estimate``'s."""

    times: np.ndarray
    poses: np.ndarray
    covariances: np.ndarray
    bias: np.ndarray
    slip: np.ndarray
    slip_score: np.ndarray
    heading: str
    twists: np.ndarray
    twist_covariances: np.ndarray
    settings: tuple[str, ...] = ()


def gyro_odometry(
    robot: Robot,
    times: object,
    increments: object,
    gyro: Gyro,
    settings: EstimatorSettings | None = None,
    *,
    initial_pose: object = None,
    commanded: object = None,
) -> GyroTrajectory:
    """A whole log: wheel-angle ``increments`` ``(N-1, 2)`` rad between ``times`` ``(N,)`` s,
    and the ``gyro``, integrated over each interval, filtered (``estimate_trajectory`` with
    ``smooth=False``). ``settings``: an ``EstimatorSettings``; its ``bias`` and ``gyro_noise``
    left None default to what the log's standing stretches give (refused for the heading
    ``"gyro"`` when the wheels never stand still; 0 for ``"fused"``, which estimates it).
    ``commanded`` ``(N-1, 2)`` rad/s, if given, are the wheel velocities commanded over each
    interval."""
    if not isinstance(gyro, Gyro):
        raise TypeError(f"gyro must be a Gyro (Gyro, Gyro.from_imu), got {type(gyro).__name__}")
    settings = settings_of(settings, EstimatorSettings)
    times, increments, turned, commanded = calibrated_log(
        times, increments, gyro, commanded, settings.sensors
    )
    assert turned is not None  # a gyro was given
    if (
        settings.heading == "gyro"
        and settings.bias is None
        and identify_standing(times, increments, turned) is None
    ):
        raise ValueError(
            "heading 'gyro' needs the gyro bias: give it (EstimatorSettings.bias, --gyro-bias), "
            "or a log in which the wheels stand still for a while"
        )
    estimate = estimate_trajectory(
        robot,
        times,
        increments,
        gyro=gyro,
        settings=settings,
        initial_pose=initial_pose,
        smooth=False,
        commanded=commanded,
    )
    return GyroTrajectory(
        times,
        estimate.poses,
        estimate.covariances,
        estimate.states[:, 3],
        estimate.slip,
        estimate.slip_score,
        settings.heading,
        estimate.twists,
        estimate.twist_covariances,
        estimate.settings,
    )


def stationary_bias(times, increments, turned, least: float = 0.5) -> float | None:
    """The gyro's mean rate (rad/s) over the intervals in which neither wheel turned, if they
    add up to ``least`` s or more; else None."""
    still = np.all(increments == 0.0, axis=1)
    duration = float(np.sum(np.diff(times)[still]))
    if duration < least:
        return None
    return float(np.sum(turned[still]) / duration)
