"""What the cores are built from: one value each, read by name by the C cores and their
pure-Python twins. ``OdometrySettings`` for ``Odometry``'s; ``CoreSettings`` for the pose
estimator's, the filter's ``Config`` (what one interval needs) and the rest of its state;
``MPPISettings`` for the MPPI cycle's, compiled and in array libraries alike; ``LogArrays``
and ``PassArrays``, a whole log's pass in and out (``EstimatorCore._run_log``)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from diffdrive._step import METHODS

__all__ = [
    "BIAS",
    "DISTANCE",
    "HEADINGS",
    "OFFSET",
    "SCALE",
    "Config",
    "CoreSettings",
    "LogArrays",
    "MPPISettings",
    "N",
    "OdometrySettings",
    "PassArrays",
]

HEADINGS = ("wheels", "gyro", "fused")  # the heading sources, in the C core's order
"""The estimator's heading sources, in the C core's order: the wheels, the gyro, or both fused."""
# the estimator's state: x, y, theta, bias, turn_scale, distance_scale, the fixes' offset x, y
N = 8
BIAS, SCALE, DISTANCE, OFFSET = 3, 4, 5, 6


@dataclass(frozen=True)
class OdometrySettings:
    """Everything an odometry core is built from, the C core and its twin alike: the
    equivalent drive ``(r_left, r_right, track, axle_offset)`` (m), the method's index in
    ``METHODS``, ``ticks_per_revolution`` (0 when not known),
    ``max_wheel_speed`` (rad/s; inf for no limit), ``counter_bits`` (0: counters that never
    roll over), the wheel noise ``k`` ``(left, right)`` (m) and ``velocity_window`` (s)."""

    drive: tuple[float, float, float, float]
    method_code: int
    ticks_per_revolution: float
    max_wheel_speed: float
    counter_bits: int
    k: tuple[float, float]
    velocity_window: float


@dataclass(frozen=True)
class Config:
    """What one interval needs besides its data: the equivalent drive ``(r_l, r_r, track,
    axle_offset)``, the method's flags, the heading source, the wheel noise (``k`` (m) and
    ``wheel_floor``, rad^2: each wheel angle increment's least variance) and the gyro's, whether
    the bias, turn scale, distance scale and the position fixes' offset are estimated, the
    offset's random walk (m^2/s), and the slip test's threshold and inflation."""

    drive: tuple[float, float, float, float]
    method: str
    heading: str
    k: tuple[float, float]
    wheel_floor: float
    arw2: float
    rrw2: float
    estimate_bias: bool
    estimate_scale: bool
    estimate_distance: bool
    estimate_offset: bool
    offset_rate2: float
    slip_threshold: float
    slip_inflation: float

    @property
    def active(self) -> list[int]:
        """The estimated states' indices, in order."""
        return (
            [0, 1, 2]
            + [BIAS] * self.estimate_bias
            + [SCALE] * self.estimate_scale
            + [DISTANCE] * self.estimate_distance
            + [OFFSET, OFFSET + 1] * self.estimate_offset
        )


@dataclass(frozen=True)
class CoreSettings(Config):
    """Everything an estimator core is built from, the C core and its Python twin alike: the
    filter's ``Config``, then the slip test's ``command_sigma`` (rad/s), the chi-square gates
    for 1, 2 and 3 dimensions, the reference point's ``offset`` (m, left of the body origin),
    whether a measurement past the gate is ``inflate``d rather than refused, ``history`` and
    ``ahead`` (s: how late and how early a measurement may be), the gyro's
    ``mounting`` row (its axis in the body frame), and the start: ``state`` ``(8,)`` and its
    ``covariance`` ``(64,)``, row-major."""

    command_sigma: float
    gates: tuple[float, float, float]
    inflate: bool
    offset: float
    history: float
    ahead: float
    mounting: tuple[float, float, float]
    state: tuple[float, ...]
    covariance: tuple[float, ...]

    @property
    def method_code(self) -> int:
        """The method's index in ``_step.METHODS`` (euler, rk2, exact), as the C core takes it."""
        return METHODS.index(self.method)

    @property
    def heading_code(self) -> int:
        """The heading source's index in ``HEADINGS``."""
        return HEADINGS.index(self.heading)


class MPPISettings(NamedTuple):
    """The MPPI cycle's numbers (``control.mppi`` fills them; see there for the maths)."""

    dt: float
    # (v, omega) to wheel commands (rad/s), row-major 2x2; the wheels' mean velocities to the
    # body twist (forward, sideways, turn), row-major 3x2.
    a00: float
    a01: float
    a10: float
    a11: float
    b00: float
    b01: float
    b10: float
    b11: float
    b20: float
    b21: float
    # The drive: its gain, the lag's decay over a period and its mean's factor, and the
    # largest change of a wheel's velocity in a period (rad/s; inf: none).
    gain: float
    decay: float
    lag_mean: float
    wheel_step: float
    # The cost weights and the limits they watch (inf: none).
    cross_track: float
    along_track: float
    heading: float
    effort: float
    rate: float
    wheel_limit: float
    max_wheel_velocity: float
    acceleration_limit: float
    max_wheel_acceleration: float
    voltage_limit: float
    max_voltage: float
    ks_left: float
    kv_left: float
    ka_left: float
    ks_right: float
    kv_right: float
    ka_right: float
    # The projection's constants (control.mppi): 1 where a voltage limit holds (0: none),
    # each wheel's kA / dt and 1 / (kV + kA / dt) (0 without a voltage limit), 1 / (1 - decay).
    voltage_bound: float
    ka_dt_left: float
    ka_dt_right: float
    volts_left: float
    volts_right: float
    undecay: float
    collision: float
    clearance: float
    footprint: float
    inflation: float
    # The clearance grid's node (0, 0) (m) and spacing (m); has_map 0: no obstacles.
    origin_x: float
    origin_y: float
    resolution: float
    has_map: float
    goal: float
    progress: float
    goal_x: float
    goal_y: float
    sigma_v: float
    sigma_omega: float


class LogArrays(NamedTuple):
    """A whole log as a core's ``_run_log`` reads it, by name, each contiguous float64:
    ``times`` ``(n,)`` s; per interval the wheels' turns ``left`` and ``right`` ``(n-1,)`` rad,
    the gyro's ``gyro`` ``(n-1,)`` rad (NaN: none) and its ``gyro_variance`` ``(n-1,)`` rad^2
    beyond the angle random walk's (``imu.Gyro.interpolation_variances``), ``forced``
    ``(n-1,)`` (nonzero: slipping whatever its score); the absolute measurements in
    ``Measurement.order``: ``m_t`` ``(M,)`` s inside the log, ``m_kind`` ``(M,)`` (an index
    into ``MEASUREMENT_KINDS``), ``m_value`` ``(M, 3)``, ``m_cov`` ``(M, 9)`` (the ``k x k``
    covariance row by row, first) and ``m_lever`` ``(M, 2)`` m."""

    times: np.ndarray
    left: np.ndarray
    right: np.ndarray
    gyro: np.ndarray
    gyro_variance: np.ndarray
    forced: np.ndarray
    m_t: np.ndarray
    m_kind: np.ndarray
    m_value: np.ndarray
    m_cov: np.ndarray
    m_lever: np.ndarray


class PassArrays(NamedTuple):
    """What a core's ``_run_log`` fills in place, by name, float64: the state ``states``
    ``(n, 8)`` and covariance ``covariances`` ``(n, 64)`` at the start and at each interval's
    end, each interval's slip flag ``slips`` and score ``scores`` ``(n,)`` (row 0: none), each
    measurement's outcome ``accepted``, squared Mahalanobis distance ``distances`` and the log
    determinant of its innovation's covariance ``log_dets`` ``(M,)``; ``records``: None, or
    room for the smoother's record of each step ``(S, RECORD_WIDTH)``."""

    states: np.ndarray
    covariances: np.ndarray
    slips: np.ndarray
    scores: np.ndarray
    accepted: np.ndarray
    distances: np.ndarray
    log_dets: np.ndarray
    records: np.ndarray | None
