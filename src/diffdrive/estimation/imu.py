"""A gyro's stream and an IMU's mounting.

``Gyro`` holds a gyro's own samples (yaw rates, or a yaw angle) and integrates them over any
interval; ``Gyro.from_imu`` turns an IMU's three rates into the body's yaw rate by its
mounting (the rotation from the IMU frame to the body frame, which must be a rotation:
``mounting_yaw_row`` checks it), ``Gyro.from_yaw`` takes a yaw angle. ``rotation_from_rpy``
builds a mounting from roll, pitch and yaw.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from diffdrive._validate import positive

__all__ = ["Gyro", "mounting_yaw_row", "rotation_from_rpy"]


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

    def calibrated(self, offset: float = 0.0, scale: float = 0.0) -> Gyro:
        """The stream on the wheels' clock and scale: a gyro whose reading taken at ``t`` on
        the wheels' clock is stamped ``t + offset`` (s), and that reads ``(1 + scale)`` times
        the turn rate (``calibrate_to_reference``'s ``gyro_offset`` and ``gyro_scale``)."""
        turn = 1.0 / (1.0 + scale)
        yaw = None if self.yaw is None else self.yaw * turn
        return Gyro(self.times - offset, self.rates * turn, self.max_gap, yaw)

    def angles(self, at: np.ndarray) -> np.ndarray:
        """The angle turned (rad) from ``times[0]`` to each time ``at`` ``(N,)``, the rate linear
        between samples; every time must lie within the gyro's span."""
        at = np.asarray(at, dtype=float)
        if at.size == 0:
            return np.zeros(at.shape)
        self._within(at)
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

    def interpolation_variances(self, at: np.ndarray) -> np.ndarray:
        """How far the samples leave the angle turned over each interval of ``at`` ``(N,)``
        open: ``(N-1,)`` rad^2. Between two samples the rate is known only at its ends; taken
        to pass from one to the other without turning back, the angle over a stretch of ``d``
        s between them lies within ``d |r1 - r0| / 2`` of the linear rate's, and is given the
        variance of a uniform error there, ``(d (r1 - r0))^2 / 12``, summed over the sample
        spans each interval holds. A rate that steps (a robot that starts to turn at once)
        is thereby not taken as exact: linear between samples it is off by up to half a
        sample's turn. From ``from_yaw``, whose angles are exact at its stamps, a whole span
        adds nothing, and a part of one the change to the next span's rate as above."""
        at = np.asarray(at, dtype=float)
        self._within(at)
        cuts = np.union1d(at, self.times[(self.times > at[0]) & (self.times < at[-1])])
        pieces = np.diff(cuts)
        middle = cuts[:-1] + 0.5 * pieces
        last = len(self.times) - 2
        span = np.clip(np.searchsorted(self.times, middle, side="right") - 1, 0, last)
        interval = np.searchsorted(at, middle, side="right") - 1
        variances = _interpolation_variance(pieces, np.diff(self.rates)[span])
        if self.yaw is not None:
            variances[pieces >= np.diff(self.times)[span]] = 0.0
        return np.bincount(interval, variances, minlength=len(at) - 1)

    def _within(self, at: np.ndarray) -> None:
        """``ValueError`` unless every time ``at`` lies within the gyro's span, naming both."""
        if at.min() < self.times[0] or at.max() > self.times[-1]:
            raise ValueError(
                f"the wheel log spans [{at.min():g}, {at.max():g}] s, the gyro only "
                f"[{self.times[0]:g}, {self.times[-1]:g}] s"
            )


def _interpolation_variance(duration, change):
    """The variance (rad^2) of the angle turned over ``duration`` s between two samples whose
    rates differ by ``change`` (rad/s), read linearly: a uniform error within half of
    ``duration * change`` either way (``Gyro.interpolation_variances``). Floats or arrays;
    past the largest float, inf (a product, not a power, which would raise)."""
    opened = duration * change
    return opened * opened / 12.0
