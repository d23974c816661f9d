"""The track width from a gyro, on any turning and without a pose reference.

Over each interval the wheels' arcs give ``u = r_r dphi_r - r_l dphi_l`` (m), and the robot
turns ``u / T`` for an effective track ``T``; a gyro measures that turn plus its bias times the
interval. So the gyro's angles regress on ``u`` with slope ``1 / T`` and on the interval's
duration with the bias. Both sides are noisy: the wheels' arcs (``k |travel|`` per wheel, as
``Odometry``, and a count's quantisation) and the gyro's angle (``angle_random_walk^2 dt``).
Ordinary least squares of the gyro on the wheels is right when the wheels are exact, and of the
wheels on the gyro when the gyro is; in between both lean, which is why a plain ratio or either
one-sided fit misses. Deming regression (errors in both variables, their variance ratio
known; Deming 1943) weighs them by their noise: the bias is found by least squares and taken
off, then the slope through the origin by Deming's formula, and its standard error by the
jackknife over ten blocks of the log. The wheel radii must be known (a gyro sees only the
track over the radii): give the robot a calibration found them in.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from diffdrive._validate import increasing, positive
from diffdrive.encoders import rounding_variance
from diffdrive.model import DiffDrive
from diffdrive.sensor_noise import DEFAULT_GYRO, GyroNoise, WheelNoise, WheelNoiseLike
from diffdrive.sensor_noise import NONE as NO_WHEEL_NOISE

__all__ = ["GyroTrack", "track_from_gyro"]


@dataclass(frozen=True)
class GyroTrack:
    """``track_from_gyro``'s result: the effective ``track`` (m), its ``standard_error`` (m),
    the gyro ``bias`` (rad/s), the ``bracket`` (m) of the two one-sided fits (the gyro on the
    wheels, as if the wheels were exact, and the wheels on the gyro, as if the gyro were),
    between which the track lies whatever the two noises, the plain ratio's track (m, the
    wheels' summed absolute turn over the gyro's) for comparison, and how many ``intervals``
    turned."""

    track: float
    standard_error: float
    bias: float
    bracket: tuple[float, float]
    plain_ratio: float
    intervals: int


def _deming(x: np.ndarray, y: np.ndarray, ratio: float) -> float:
    """The slope of ``y = s x`` through the origin, errors in both, ``ratio`` = var(y noise) /
    var(x noise)."""
    sxx, syy, sxy = float(x @ x), float(y @ y), float(x @ y)
    if ratio == math.inf:
        return sxy / sxx
    spread = syy - ratio * sxx
    return (spread + math.sqrt(spread * spread + 4.0 * ratio * sxy * sxy)) / (2.0 * sxy)


def track_from_gyro(
    robot: DiffDrive,
    times: object,
    increments: object,
    gyro_angles: object,
    *,
    wheel_noise: WheelNoiseLike = NO_WHEEL_NOISE,
    ticks_per_revolution: float | None = None,
    gyro_noise: GyroNoise = DEFAULT_GYRO,
) -> GyroTrack:
    """The effective track of ``robot`` (its wheel radii taken as right; its track is not
    used) from wheel-angle
    ``increments`` ``(N-1, 2)`` rad between ``times`` ``(N,)`` s and the angles the gyro turned
    over the same intervals ``gyro_angles`` ``(N-1,)`` rad (``Gyro.angles`` differenced): see
    the module. ``wheel_noise`` (a ``WheelNoise``; default none, wheels read exactly),
    ``ticks_per_revolution`` and ``gyro_noise``'s angle random walk (a ``GyroNoise``; default
    ``DEFAULT_GYRO``'s) are the two sides' noise: the answer depends on their ratio, between
    the ``bracket``'s ends."""
    times = np.asarray(times, dtype=float)
    increments = np.asarray(increments, dtype=float)
    angles = np.asarray(gyro_angles, dtype=float)
    if (
        times.ndim != 1
        or increments.shape != (len(times) - 1, 2)
        or angles.shape != (len(times) - 1,)
    ):
        raise ValueError(
            f"times (N,), increments (N-1, 2) and gyro_angles (N-1,) must agree, got "
            f"{times.shape}, {increments.shape} and {angles.shape}"
        )
    if not (
        np.all(np.isfinite(times))
        and np.all(np.isfinite(increments))
        and np.all(np.isfinite(angles))
    ):
        raise ValueError("times, increments and gyro_angles must be finite")
    increasing("times", times)
    k = WheelNoise.coerce(wheel_noise).k
    if ticks_per_revolution is not None:
        positive("ticks_per_revolution", ticks_per_revolution)
    if not isinstance(gyro_noise, GyroNoise):
        raise TypeError(f"gyro_noise must be a GyroNoise, got {type(gyro_noise).__name__}")
    dt = np.diff(times)
    r_l, r_r = robot.left_wheel_radius, robot.right_wheel_radius
    arcs = increments * np.array([r_l, r_r])
    u = arcs[:, 1] - arcs[:, 0]
    turned = np.abs(u) > 0
    if np.count_nonzero(turned) >= 20:
        # The bias: least squares of the gyro on (u, dt), then taken off.
        design = np.column_stack([u, dt])
        (_, bias), *_ = np.linalg.lstsq(design, angles, rcond=None)
    else:
        bias = 0.0
    y = angles - bias * dt
    # The turn as the gyro saw it: the robot's own track is what is sought, not a measure.
    if np.count_nonzero(turned) < 20 or float(np.sum(np.abs(y))) < 0.05:
        raise ValueError(
            "the log does not turn enough to find the track from a gyro: it needs turning "
            "(20 intervals or more, and a turn of a few degrees or more in all)"
        )
    wheel = float(np.mean(np.abs(arcs) @ k))  # each wheel's travel variance, summed
    if ticks_per_revolution is not None:  # a count's quantisation on each wheel
        wheel += (r_l * r_l + r_r * r_r) * rounding_variance(ticks_per_revolution)
    gyro = gyro_noise.angle_random_walk**2 * float(np.mean(dt))
    ratio = math.inf if wheel == 0 else gyro / wheel  # var(y noise) / var(x noise), rad^2/m^2
    slope = _deming(u, y, ratio)
    if not slope > 0.0:
        # The gyro turns one way when the wheels turn the other: its sign, not a track.
        raise ValueError(
            "the gyro turns against the wheels (a track < 0): an IMU mounted upside down or "
            "a gyro of the other sign (--imu-rpy 180 0 0), or the wheels swapped"
        )
    blocks = np.array_split(np.arange(len(u)), 10)
    leave_out = []
    for block in blocks:
        keep = np.ones(len(u), dtype=bool)
        keep[block] = False
        leave_out.append(1.0 / _deming(u[keep], y[keep], ratio))
    leave_out_array = np.array(leave_out)
    spread = math.sqrt((len(blocks) - 1) * np.var(leave_out_array))
    plain = float(np.sum(np.abs(u)) / np.sum(np.abs(angles)))
    bracket = (float(u @ u / (u @ y)), float(u @ y / (y @ y)))
    return GyroTrack(
        1.0 / slope, spread, float(bias), bracket, plain, int(np.count_nonzero(turned))
    )
