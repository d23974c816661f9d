"""A synthetic yaw gyro: what an IMU mounted on the robot would read along a trajectory.

The true yaw rate at each sample (between two intervals, the mean of their rates weighed by
their durations, each rate the trajectory's turn over an interval over its duration; at the
ends, the end interval's) is read with the error terms ``diffdrive.estimation.gyro`` states
(IEEE Std 952-1997):

    rate = (1 + scale) omega + bias + b_in(t) + b_rw(t) + white

- ``bias`` (rad/s), a constant;
- ``scale`` (relative), an error of the gain;
- ``noise``, a ``GyroNoise`` (``diffdrive.sensor_noise``, the type the estimators assume):
  ``bias_instability`` (rad/s), a first-order Gauss-Markov bias of that standard deviation
  and ``correlation_time`` (s), started from its stationary distribution;
  ``rate_random_walk`` (rad/s/sqrt(s)), a bias that random-walks, from 0;
  ``angle_random_walk`` (rad/s/sqrt(Hz)), white rate noise of standard deviation
  ``arw / sqrt(dt)`` over a sample of ``dt`` s, so that the angle's variance grows by
  ``arw^2 dt``. Its ``initial_bias_sigma`` is an estimator's, not drawn here.

The reading is the body's yaw rate; an IMU reports three rates in its own frame:
``angular_velocity`` is the body vector ``(0, 0, rate)`` turned into the IMU frame by
``mounting`` (the rotation from the IMU frame to the body frame, as ``Gyro.from_imu`` takes it),
so that ``Gyro.from_imu(times, angular_velocity[n], mounting)`` gives ``rates[n]`` back.
``angles`` integrates the rates linearly between samples, as ``Gyro`` reads a gyro's rates.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from diffdrive._validate import finite, rng_of
from diffdrive.model import Robot
from diffdrive.sensor_noise import GyroNoise
from diffdrive.sensors.motion import motion_of

__all__ = ["GyroModel", "GyroReadings", "gyro_readings"]

NO_GYRO_NOISE = GyroNoise()  # an ideal gyro: a synthetic gyro draws only the noise it is given


@dataclass(frozen=True)
class GyroModel:
    """The gyro's error terms (see the module); every default is the ideal gyro."""

    bias: float = 0.0
    scale: float = 0.0
    noise: GyroNoise = NO_GYRO_NOISE
    mounting: Any = None

    def __post_init__(self) -> None:
        finite("bias", self.bias)
        finite("scale", self.scale)
        if not isinstance(self.noise, GyroNoise):
            raise TypeError(f"noise must be a GyroNoise, got {type(self.noise).__name__}")
        rotation = self.rotation
        orthonormal = np.allclose(rotation @ rotation.T, np.eye(3), atol=1e-9)
        if not (orthonormal and np.linalg.det(rotation) > 0):
            raise ValueError("mounting is not a rotation (orthonormal, determinant +1)")

    @property
    def rotation(self) -> np.ndarray:
        """The mounting, IMU frame to body frame (default: the identity, z up)."""
        rotation = np.eye(3) if self.mounting is None else np.asarray(self.mounting, dtype=float)
        if rotation.shape != (3, 3) or not np.all(np.isfinite(rotation)):
            raise ValueError(f"mounting must be a finite 3x3 rotation, got {self.mounting!r}")
        return rotation


@dataclass(frozen=True, eq=False)
class GyroReadings:
    """``rates`` ``(N, M)`` rad/s at ``times`` ``(M,)``; ``truth`` ``(B, M)`` the true yaw
    rates; ``bias`` ``(N, M)`` the whole bias at each sample (constant, instability and
    random walk); ``model`` the terms."""

    times: np.ndarray
    rates: np.ndarray
    truth: np.ndarray
    bias: np.ndarray
    model: GyroModel

    @property
    def angles(self) -> np.ndarray:
        """The angle turned from the first sample, the rate linear between samples (as
        ``Gyro.angles`` integrates it): ``(N, M)`` rad."""
        turned = 0.5 * (self.rates[:, 1:] + self.rates[:, :-1]) * np.diff(self.times)
        return np.concatenate([np.zeros((len(self.rates), 1)), np.cumsum(turned, axis=1)], 1)

    @property
    def angular_velocity(self) -> np.ndarray:
        """The IMU's three rates in its own frame ``(N, M, 3)``: what ``sensor_msgs/Imu``
        carries (``Gyro.from_imu`` with the ``mounting`` reads ``rates`` back)."""
        return self.rates[..., None] * self.model.rotation[2]


def gyro_readings(
    robot: Robot,
    times: object,
    poses: object,
    model: GyroModel | None = None,
    *,
    robots: int | None = None,
    seed: int | None = None,
) -> GyroReadings:
    """What the gyros of ``robots`` robots read at the trajectory's ``times`` (see the
    module), the errors drawn from ``seed``."""
    model = GyroModel() if model is None else model
    noise = model.noise
    motion = motion_of(robot, times, poses)
    count = motion.robots(robots)
    rng = rng_of(seed)
    durations = motion.durations
    omega = motion.increments[..., 2] / durations  # (B, T): each interval's mean rate
    # At a sample, its two intervals' mean rates weighed by their durations: each interval's
    # turn shared evenly between its two ends, so that linear interpolation between samples
    # (Gyro.angles) integrates back the whole run's turn exactly, on even and uneven stamps
    # alike. At a sample m between, the angle is off by d[m-1] d[m] (w[m] - w[m-1]) /
    # (2 (d[m-1] + d[m])), the trapezoid's own error where the rate steps (no sampled rates
    # do better: matching every interval's turn would make them alternate without end).
    before, after = durations[:-1], durations[1:]
    inner = (omega[:, :-1] * before + omega[:, 1:] * after) / (before + after)
    truth = np.concatenate([omega[:, :1], inner, omega[:, -1:]], 1)
    samples = len(motion.times)
    bias = np.full((count, samples), model.bias)
    # Each sample's noise spans the interval it starts (the last, the one before it).
    spans = np.concatenate([durations, durations[-1:]])
    if noise.bias_instability:
        decay = np.exp(-durations / noise.correlation_time)
        drive = noise.bias_instability * np.sqrt(1.0 - decay**2)
        markov = np.empty((count, samples))
        markov[:, 0] = noise.bias_instability * rng.standard_normal(count)
        for k in range(1, samples):
            markov[:, k] = decay[k - 1] * markov[:, k - 1] + drive[k - 1] * rng.standard_normal(
                count
            )
        bias += markov
    if noise.rate_random_walk:
        steps = (
            noise.rate_random_walk * np.sqrt(durations) * rng.standard_normal((count, samples - 1))
        )
        bias[:, 1:] += np.cumsum(steps, axis=1)
    rates = (1.0 + model.scale) * truth + bias
    if noise.angle_random_walk:
        rates = rates + noise.angle_random_walk / np.sqrt(spans) * rng.standard_normal(rates.shape)
    if not np.all(np.isfinite(rates)):
        raise ValueError("the gyro's rates overflow: the trajectory turns too fast for floats")
    return GyroReadings(motion.times, rates, np.broadcast_to(truth, rates.shape), bias, model)
