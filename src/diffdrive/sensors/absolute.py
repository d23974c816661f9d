"""Synthetic absolute sensors: a pose (camera, AprilTag, localiser) or a position (GPS).

Each measurement is of the true pose at its ``times`` (the trajectory's, or every
``period`` s), interpolated along the trajectory (positions linearly, the unwrapped heading
linearly), with Gaussian noise of ``sigma`` ``(x, y, theta)`` (m, m, rad); it arrives
``latency`` s later (``arrival``: what a fusion filter sees late and out of order), is lost with
probability ``dropout``, and is an ``outlier`` with probability ``outlier``: moved by a
uniform direction and ``outlier_distance`` m (and a uniform heading). Outliers are labelled.
A receiver that ``wander``s (m/sqrt(s)) adds an offset to the positions, a random walk from
zero at the first measurement in each axis (``offsets``): multipath and the satellites moving,
what ``estimate_trajectory(..., fixes="identified")`` takes as the fixes' offset.

The sensor sits at ``mount`` ``(x, y, yaw)`` (m, m, rad) on the robot: it measures its own
pose, the robot's composed with the mount (a GPS antenna's position, a camera's pose). Its
clock runs ``clock_offset`` s ahead of the wheels': a reading taken at ``t`` is stamped
``t + clock_offset`` (``times``), what ``calibration.calibrate_to_reference`` estimates.

A position sensor (``position_only``) has no heading; ``geodetic`` turns its positions into
latitude and longitude (deg) and height (m) about an origin, through the local east-north-up
frame (pymap3d, the ``ros`` extra): the world frame's x is east and y north.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from diffdrive import batch
from diffdrive._validate import finite, geodetic_point, positive, rng_of
from diffdrive.model import Robot
from diffdrive.sensors.motion import motion_of

__all__ = ["AbsoluteModel", "AbsoluteReadings", "absolute_readings"]


@dataclass(frozen=True)
class AbsoluteModel:
    """An absolute sensor's terms (see the module); the defaults are a perfect pose sensor
    sampled with the trajectory."""

    sigma: tuple[float, float, float] = (0.0, 0.0, 0.0)
    period: float | None = None
    latency: float = 0.0
    dropout: float = 0.0
    outlier: float = 0.0
    outlier_distance: float = 1.0
    position_only: bool = False
    wander: float = 0.0
    mount: tuple[float, float, float] = (0.0, 0.0, 0.0)
    clock_offset: float = 0.0

    def __post_init__(self) -> None:
        if len(self.sigma) != 3 or not all(finite("sigma", s) >= 0.0 for s in self.sigma):
            raise ValueError(f"sigma must be 3 standard deviations >= 0, got {self.sigma!r}")
        if self.period is not None:
            positive("period", self.period)
        if not finite("latency", self.latency) >= 0.0:
            raise ValueError(f"latency must be >= 0, got {self.latency!r}")
        for name in ("dropout", "outlier"):
            if not 0.0 <= finite(name, getattr(self, name)) < 1.0:
                raise ValueError(
                    f"{name} must be a probability in [0, 1), got {getattr(self, name)!r}"
                )
        positive("outlier_distance", self.outlier_distance)
        if not finite("wander", self.wander) >= 0.0:
            raise ValueError(f"wander must be >= 0 m/sqrt(s), got {self.wander!r}")
        if len(self.mount) != 3:
            raise ValueError(f"mount must be (x, y, yaw) (m, m, rad), got {self.mount!r}")
        for value in self.mount:
            finite("mount", value)
        finite("clock_offset", self.clock_offset)


@dataclass(frozen=True, eq=False)
class AbsoluteReadings:
    """``poses`` ``(N, M, 3)`` measured, stamped ``times`` ``(M,)`` (the sensor's clock;
    ``theta`` NaN for a position sensor), arriving at ``arrival`` ``(M,)`` (the wheels'
    clock); ``kept`` ``(N, M)`` those not lost; ``outliers`` ``(N, M)`` the labels; ``truth``
    ``(B, M, 3)`` the sensor's true poses then (the robot's composed with the mount); ``model``
    its terms; ``offsets`` ``(N, M, 2)`` the wandering receiver's offsets (m; zero without
    ``wander``)."""

    times: np.ndarray
    arrival: np.ndarray
    poses: np.ndarray
    kept: np.ndarray
    outliers: np.ndarray
    truth: np.ndarray
    model: AbsoluteModel
    offsets: np.ndarray

    def geodetic(self, origin: tuple[float, float, float]) -> np.ndarray:
        """Latitude, longitude (deg) and height (m) of the positions ``(N, M, 3)``, about the
        ``origin`` (lat deg, lon deg, height m) at the world frame's origin, x east, y north."""
        try:
            import pymap3d
        except ImportError:
            raise ImportError("geodetic needs pymap3d: pip install 'diffdrive[ros]'") from None
        lat0, lon0, h0 = geodetic_point("origin", origin)
        east, north = self.poses[..., 0], self.poses[..., 1]
        lat, lon, height = pymap3d.enu2geodetic(east, north, np.zeros_like(east), lat0, lon0, h0)
        return np.stack([lat, lon, height], axis=-1)


def absolute_readings(
    robot: Robot,
    times: object,
    poses: object,
    model: AbsoluteModel | None = None,
    *,
    robots: int | None = None,
    seed: int | None = None,
) -> AbsoluteReadings:
    """What an absolute sensor on each of ``robots`` robots measures along the trajectory
    (see the module), drawn from ``seed``."""
    model = AbsoluteModel() if model is None else model
    motion = motion_of(robot, times, poses)
    count = motion.robots(robots)
    rng = rng_of(seed)
    t = motion.times
    at = t if model.period is None else np.arange(t[0], t[-1] + 1e-9 * model.period, model.period)
    truth = np.stack(
        [
            np.stack(
                [np.interp(at, t, p[:, 0]), np.interp(at, t, p[:, 1]), np.interp(at, t, h)], -1
            )
            for p, h in zip(motion.poses, motion.headings, strict=True)
        ]
    )
    if any(model.mount):
        truth = batch.compose(truth, np.asarray(model.mount, dtype=float))
    measured = truth + np.asarray(model.sigma) * rng.standard_normal((count, len(at), 3))
    outliers = (
        rng.random((count, len(at))) < model.outlier
        if model.outlier
        else np.zeros((count, len(at)), dtype=bool)
    )
    if outliers.any():
        direction = rng.uniform(-math.pi, math.pi, outliers.sum())
        measured[outliers, 0] += model.outlier_distance * np.cos(direction)
        measured[outliers, 1] += model.outlier_distance * np.sin(direction)
        measured[outliers, 2] += rng.uniform(-math.pi, math.pi, outliers.sum())
    if model.position_only:
        measured[..., 2] = np.nan
    kept = np.ones((count, len(at)), dtype=bool)
    if model.dropout:
        kept = rng.random((count, len(at))) >= model.dropout
    offsets = np.zeros((count, len(at), 2))
    if model.wander:  # drawn last: the other terms' draws are the same with or without it
        spans = np.sqrt(np.diff(at, prepend=at[0]))[None, :, None]
        offsets = np.cumsum(model.wander * spans * rng.standard_normal(offsets.shape), axis=1)
        measured[..., :2] += offsets
    stamps = at + model.clock_offset
    return AbsoluteReadings(
        stamps, at + model.latency, measured, kept, outliers, truth, model, offsets
    )
