"""The pose estimator's settings as one value: ``EstimatorSettings``, made of small values that
each check themselves and carry one documented default.

``PoseEstimator`` (streaming), ``GyroOdometry``, ``estimate_trajectory`` and ``gyro_odometry``
(whole logs) and the command line all take one ``EstimatorSettings``; ``dataclasses.replace``
changes a part, checked again. The parts:

- ``heading``: the heading's source, ``"wheels"``, ``"gyro"`` or ``"fused"`` (default; the
  filter's maths: ``diffdrive.estimation.filter``);
- ``wheel_noise``: a ``WheelNoise`` (a number ``k`` (m) or a pair is read as one). None, the
  default: a whole log with a gyro identifies it from the wheels' turn against the gyro's
  (``wheel_turns.identify_wheel_turns``); without one, and in a streaming estimator,
  ``sensor_noise.DEFAULT``;
- ``gyro_noise`` and ``bias``: the gyro's ``GyroNoise`` and its bias's start (rad/s). None, the
  default: a whole log identifies them from its standing stretches
  (``standing.identify_standing``); where it has none, and in a streaming estimator,
  ``sensor_noise.DEFAULT_GYRO`` and 0 rad/s;
- ``turn_scale`` and ``distance_scale``: each a ``Prior`` (its start and the prior's standard
  deviation; 0, the default: not estimated). ``distance_scale`` None (the default): ``Prior()``,
  or with identified fixes the fixes' fit;
- ``fix_offset``: the ``FixOffset`` of the position fixes (its random walk and its start's
  spread); None (the default): no offset state, or with identified fixes the wander found;
- ``gate``: the ``Gate`` of absolute measurements; None (the default): ``Gate()``, or with
  identified fixes a wide gate whose outliers are inflated (``fixes.IDENTIFIED_GATE``);
- ``slip``: the ``SlipTest``'s threshold, inflation and command spread;
- ``window``: how late (``history``) and how early (``ahead``) a streaming estimator takes a
  measurement (``Window``); a whole log keeps all of itself and waits for nothing;
- ``method``: the integration of each interval, ``"euler"``, ``"rk2"`` or ``"exact"`` (default);
- ``mounting``: the rotation from the IMU's frame to the body's (3x3), for three IMU rates;
  None (default): the identity;
- ``encoders``: the wheel readings' ``Encoders`` (counts per revolution, counter width, top
  speed), as ``Odometry`` takes them;
- ``sensors``: what a calibration found of the other sensors (``SensorCalibration``): the
  gyro's clock and scale, the absolute measurements' lever arm; default: none of them
  (``ReferenceCalibration.estimator_settings`` fills it, with the scales and the bias);
- ``whole_log``: what only a whole log does (``WholeLog``): the slip episodes, the fixes'
  identification, the smoother's records.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from diffdrive._validate import finite, nonnegative, positive
from diffdrive.backends.settings import HEADINGS
from diffdrive.encoders import check_counter_bits, rounding_variance
from diffdrive.estimation.filter import SLIP_THRESHOLD
from diffdrive.estimation.imu import mounting_yaw_row
from diffdrive.estimation.measurements import Measurement
from diffdrive.integrate import Method, check_method
from diffdrive.sensor_noise import DEFAULT, DEFAULT_GYRO, GyroNoise, WheelNoise

__all__ = [
    "OUTLIERS",
    "PARTS",
    "SLIP_THRESHOLD",
    "Encoders",
    "EstimatorSettings",
    "FixOffset",
    "Gate",
    "Prior",
    "SensorCalibration",
    "SlipTest",
    "WholeLog",
    "Window",
]

OUTLIERS = ("refuse", "inflate")  # what the gate does with a measurement past it
FIXES = ("given", "identified")
Heading = Literal["wheels", "gyro", "fused"]


def _kind(owner: str, name: str, value: object, kind: type) -> None:
    """``TypeError`` naming ``owner.name`` unless ``value`` is a ``kind`` (booleans are no
    numbers here)."""
    if not isinstance(value, kind) or (kind is not bool and isinstance(value, bool)):
        raise TypeError(f"{owner}.{name} must be a {kind.__name__}, got {value!r}")


@dataclass(frozen=True)
class Prior:
    """A scale state's ``start`` (> 0; 1: the wheels' own figure) and its prior standard
    deviation ``sigma`` (>= 0; 0: not estimated, held at ``start``)."""

    start: float = 1.0
    sigma: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "start", positive("Prior.start", self.start))
        object.__setattr__(self, "sigma", nonnegative("Prior.sigma", self.sigma))
        if not math.isfinite(self.sigma * self.sigma):
            raise ValueError(f"Prior.sigma {self.sigma!r} squares past the largest float")

    @property
    def estimated(self) -> bool:
        """Whether the state is estimated (``sigma`` > 0)."""
        return self.sigma > 0.0


@dataclass(frozen=True)
class FixOffset:
    """The offset (m, world frame) the ``"position"`` fixes carry from the point they fix: a
    random walk of ``rate`` (m/sqrt(s); a receiver's wander) from a start of spread ``sigma``
    (m; 0: the offset starts at zero, the first fixes placing the robot). Both 0: no offset
    state, the fixes' error is white."""

    rate: float = 0.0
    sigma: float = 0.0

    def __post_init__(self) -> None:
        for name in ("rate", "sigma"):
            value = nonnegative(f"FixOffset.{name}", getattr(self, name))
            if not math.isfinite(value * value):
                raise ValueError(f"FixOffset.{name} {value!r} squares past the largest float")
            object.__setattr__(self, name, value)

    @property
    def estimated(self) -> bool:
        """Whether the offset is a state (either figure > 0)."""
        return self.rate > 0.0 or self.sigma > 0.0


@dataclass(frozen=True)
class Gate:
    """The chi-square gate of absolute measurements: ``probability`` inside it (0 to 1,
    exclusive) and what becomes of a measurement past it, ``outliers``: ``"refuse"`` (left out,
    counted in ``rejected``) or ``"inflate"`` (taken with its covariance grown until it lies on
    the gate: a heavy-tailed sensor's jumps followed, not lost)."""

    probability: float = 0.999
    outliers: Literal["refuse", "inflate"] = "refuse"

    def __post_init__(self) -> None:
        probability = finite("Gate.probability", self.probability)
        if not 0.0 < probability < 1.0:
            raise ValueError(f"Gate.probability must be in (0, 1), got {self.probability!r}")
        object.__setattr__(self, "probability", probability)
        if self.outliers not in OUTLIERS:
            raise ValueError(
                f"Gate.outliers must be one of {', '.join(OUTLIERS)}, got {self.outliers!r}"
            )


@dataclass(frozen=True)
class SlipTest:
    """The slip tests: an interval whose wheel turn and gyro turn differ by more than
    ``threshold`` (chi-square, one degree of freedom; default P = 0.001) is flagged, its wheel
    turn left out and its wheel noise multiplied by ``inflation``; ``command_sigma`` (rad/s) is
    how far a wheel may run from its command before the command test flags it."""

    threshold: float = SLIP_THRESHOLD
    inflation: float = 100.0
    command_sigma: float = 1.0

    def __post_init__(self) -> None:
        for name in ("threshold", "inflation", "command_sigma"):
            object.__setattr__(self, name, positive(f"SlipTest.{name}", getattr(self, name)))
        if not 0.0 < self.command_sigma * self.command_sigma < math.inf:
            raise ValueError(
                f"SlipTest.command_sigma {self.command_sigma!r} squares to 0 or past the floats"
            )


@dataclass(frozen=True)
class Window:
    """How late and how early a streaming estimator takes an absolute measurement: ``history``
    (s, > 0; inf: all of it) of wheel intervals are kept to replay a late one, and one up to
    ``ahead`` (s, >= 0) past the newest wheel reading waits for the wheels."""

    history: float = 2.0
    ahead: float = 0.1

    def __post_init__(self) -> None:
        if self.history != math.inf:
            object.__setattr__(self, "history", positive("Window.history", self.history))
        else:
            object.__setattr__(self, "history", math.inf)
        object.__setattr__(self, "ahead", nonnegative("Window.ahead", self.ahead))


@dataclass(frozen=True)
class Encoders:
    """The wheel readings: ``ticks_per_revolution`` (counts per wheel revolution; needed for
    counter readings), ``counter_bits`` (2 to 64; None: counters that never roll over) and
    ``max_wheel_speed`` (rad/s; None: no limit), past which a jump is refused: as ``Odometry``
    takes them. The counts also set the filter's ``wheel_floor``."""

    ticks_per_revolution: float | None = None
    counter_bits: int | None = None
    max_wheel_speed: float | None = None

    def __post_init__(self) -> None:
        if self.ticks_per_revolution is not None:
            ticks = positive("Encoders.ticks_per_revolution", self.ticks_per_revolution)
            if not math.isfinite(2.0 * math.pi / ticks):
                raise ValueError(
                    "Encoders.ticks_per_revolution must give a finite angle per count, got "
                    f"{self.ticks_per_revolution!r}"
                )
            object.__setattr__(self, "ticks_per_revolution", ticks)
        object.__setattr__(self, "counter_bits", check_counter_bits(self.counter_bits))
        if self.max_wheel_speed is not None:
            speed = positive("Encoders.max_wheel_speed", self.max_wheel_speed)
            object.__setattr__(self, "max_wheel_speed", speed)

    @property
    def wheel_floor(self) -> float:
        """The least variance (rad^2) of a wheel angle increment read off these counters: the
        difference of two readings, each rounded to a count (``encoders.rounding_variance``);
        0 without the counts."""
        if self.ticks_per_revolution is None:
            return 0.0
        return rounding_variance(self.ticks_per_revolution)


@dataclass(frozen=True)
class SensorCalibration:
    """What a calibration found of the sensors beside the wheels, as ``calibrate_to_reference``
    names it. The gyro: its clock ``gyro_offset`` (s; a reading taken at ``t`` on the wheels'
    clock is stamped ``t + gyro_offset``) and ``gyro_scale`` (it reads ``(1 + gyro_scale)``
    times the turn rate, > -1). The absolute measurements' sensor: its clock ``offset`` (s,
    likewise), its ``lever_arm`` (m, body frame; None: each measurement's own), where it sits
    (a GPS antenna, a camera), and a pose sensor's ``yaw`` on the body (rad: it reads the
    body's heading plus ``yaw``).

    A whole log (``estimate_trajectory``) moves the gyro's stamps onto the wheels' clock and
    divides its rates by the scale before integrating them; every estimator moves each
    measurement's stamp back by ``offset``, turns a pose's heading back by ``yaw`` and gives
    the lever arm to one made without its own (one with another is refused). A streaming
    estimator takes each interval's gyro angle as given, so it refuses a gyro offset or scale
    (integrate the readings of ``Gyro.calibrated`` instead)."""

    gyro_offset: float = 0.0
    gyro_scale: float = 0.0
    offset: float = 0.0
    lever_arm: tuple[float, float] | None = None
    yaw: float = 0.0

    def __post_init__(self) -> None:
        for name in ("gyro_offset", "gyro_scale", "offset", "yaw"):
            object.__setattr__(self, name, finite(f"SensorCalibration.{name}", getattr(self, name)))
        if not self.gyro_scale > -1.0:
            raise ValueError(
                f"SensorCalibration.gyro_scale must be > -1 (a gyro that reads the turn's "
                f"sign), got {self.gyro_scale!r}"
            )
        if self.lever_arm is not None:
            arm = np.asarray(self.lever_arm, dtype=float)
            if arm.shape != (2,) or not np.all(np.isfinite(arm)):
                raise ValueError(
                    f"SensorCalibration.lever_arm must be two finite numbers (m), got "
                    f"{self.lever_arm!r}"
                )
            object.__setattr__(self, "lever_arm", (float(arm[0]), float(arm[1])))

    @property
    def gyro_calibrated(self) -> bool:
        """Whether the gyro's clock or scale is other than the wheels' own."""
        return self.gyro_offset != 0.0 or self.gyro_scale != 0.0

    @property
    def measurements_calibrated(self) -> bool:
        """Whether the absolute measurements are moved (clock, lever arm, yaw)."""
        return self.offset != 0.0 or self.lever_arm is not None or self.yaw != 0.0

    def placed(self, measurement: Measurement) -> Measurement:
        """``measurement`` on the wheels' clock, with the sensor's lever arm where it has
        none and a pose's heading the body's; ``ValueError`` naming it where it carries a
        lever arm other than ``lever_arm``."""
        if not self.measurements_calibrated:
            return measurement
        m = measurement
        arm = m.lever_arm
        if self.lever_arm is not None and m.kind != "heading" and arm != self.lever_arm:
            if arm != (0.0, 0.0):
                raise ValueError(
                    f"{m.kind} measurement at t = {m.t!r} s carries the lever arm {arm} m and "
                    f"the settings another, {self.lever_arm} m (SensorCalibration.lever_arm): "
                    "give one of them"
                )
            arm = self.lever_arm
        value = m.value
        if m.kind == "pose" and self.yaw != 0.0:
            value = value.copy()
            value[2] -= self.yaw
        return Measurement.make(m.kind, m.t - self.offset, value, m.covariance, arm)


@dataclass(frozen=True)
class WholeLog:
    """What only a whole log (``estimate_trajectory``) does. ``slip_episodes``: besides the
    intervals the streaming test flags, flag the runs of intervals one slipping wheel explains
    (``diffdrive.estimation.episodes``; the log then runs again with them flagged); False: the
    streaming test's alone. ``fixes``: what the ``"position"`` measurements are worth,
    ``"given"`` (their covariance, white) or ``"identified"`` from the fixes themselves
    (``diffdrive.estimation.fixes``). ``records``: keep the smoother's record of every step
    (1,664 bytes a step; needs the smoother)."""

    slip_episodes: bool = True
    fixes: Literal["given", "identified"] = "given"
    records: bool = False

    def __post_init__(self) -> None:
        _kind("WholeLog", "slip_episodes", self.slip_episodes, bool)
        _kind("WholeLog", "records", self.records, bool)
        if self.fixes not in FIXES:
            raise ValueError(
                f"WholeLog.fixes must be one of {', '.join(FIXES)}, got {self.fixes!r}"
            )


@dataclass(frozen=True)
class EstimatorSettings:
    """Everything the pose estimator is set up with but the robot and its start (see the
    module for each part and its default)."""

    heading: Heading = "fused"
    wheel_noise: WheelNoise | None = None
    gyro_noise: GyroNoise | None = None
    bias: float | None = None
    turn_scale: Prior = field(default_factory=Prior)
    distance_scale: Prior | None = None
    fix_offset: FixOffset | None = None
    gate: Gate | None = None
    slip: SlipTest = field(default_factory=SlipTest)
    window: Window = field(default_factory=Window)
    method: Method = "exact"
    mounting: tuple[tuple[float, float, float], ...] | None = None
    encoders: Encoders = field(default_factory=Encoders)
    sensors: SensorCalibration = field(default_factory=SensorCalibration)
    whole_log: WholeLog = field(default_factory=WholeLog)

    def __post_init__(self) -> None:
        if self.heading not in HEADINGS:
            raise ValueError(
                f"EstimatorSettings.heading must be one of {', '.join(HEADINGS)}, got "
                f"{self.heading!r}"
            )
        if self.wheel_noise is not None:
            noise = WheelNoise.coerce(self.wheel_noise, "EstimatorSettings.wheel_noise")
            object.__setattr__(self, "wheel_noise", noise)
        if self.bias is not None:
            object.__setattr__(self, "bias", finite("EstimatorSettings.bias", self.bias))
        for name, (kind, optional) in PARTS.items():
            value = getattr(self, name)
            if name != "wheel_noise" and not (optional and value is None):
                _kind("EstimatorSettings", name, value, kind)
        check_method(self.method)
        if self.mounting is not None:
            rotation = np.asarray(self.mounting, dtype=float)
            mounting_yaw_row(rotation)  # a rotation, or ValueError naming it
            rows = tuple(tuple(float(v) for v in row) for row in rotation)
            object.__setattr__(self, "mounting", rows)

    # What a streaming estimator takes where a whole log would identify (see the module).

    @property
    def wheels(self) -> WheelNoise:
        """``wheel_noise``, else ``sensor_noise.DEFAULT``."""
        return DEFAULT if self.wheel_noise is None else self.wheel_noise

    @property
    def gyro(self) -> GyroNoise:
        """``gyro_noise``, else ``sensor_noise.DEFAULT_GYRO``."""
        return DEFAULT_GYRO if self.gyro_noise is None else self.gyro_noise

    @property
    def bias_start(self) -> float:
        """``bias``, else 0 rad/s."""
        return 0.0 if self.bias is None else self.bias

    @property
    def distance(self) -> Prior:
        """``distance_scale``, else ``Prior()``."""
        return Prior() if self.distance_scale is None else self.distance_scale

    @property
    def offset(self) -> FixOffset:
        """``fix_offset``, else ``FixOffset()`` (no offset state)."""
        return FixOffset() if self.fix_offset is None else self.fix_offset

    @property
    def gating(self) -> Gate:
        """``gate``, else ``Gate()``."""
        return Gate() if self.gate is None else self.gate

    def replace(self, **changes: object) -> EstimatorSettings:
        """A copy with ``changes`` (parts by name), checked again."""
        return dataclasses.replace(self, **changes)  # type: ignore[arg-type]

    def changed(self, changes: Mapping[str, object]) -> EstimatorSettings:
        """A copy with ``changes`` by name, as a settings file or the command line gives them:
        a part (``"bias"``, ``"heading"``) or one field of a part (``"gate.probability"``; a
        part that is None starts from its own defaults, the wheels' from ``wheels``).
        ``ValueError`` names an unknown one; each part checks its values as ever."""
        if not isinstance(changes, Mapping):
            raise TypeError(
                f"changes must be a mapping of setting names to values, got {changes!r}"
            )
        parts: dict[str, object] = {}
        known = [item.name for item in dataclasses.fields(self)]
        for key, value in changes.items():
            name, dot, inner = key.partition(".")
            if name not in known:
                raise ValueError(f"unknown setting {key!r}; the parts: {', '.join(known)}")
            if not dot:
                parts[name] = value
                continue
            if name not in PARTS:
                raise ValueError(f"setting {key!r}: {name} is one value, with no fields")
            kind = PARTS[name][0]
            fields = [item.name for item in dataclasses.fields(kind)]
            if inner not in fields:
                raise ValueError(f"unknown setting {key!r}; {name}'s fields: {', '.join(fields)}")
            current: Any = parts.get(name, getattr(self, name))
            if current is None:
                current = self.wheels if name == "wheel_noise" else kind()
            parts[name] = dataclasses.replace(current, **{inner: value})
        return dataclasses.replace(self, **parts)  # type: ignore[arg-type]


# The parts that are values of their own, and whether each may be None.
PARTS: dict[str, tuple[type, bool]] = {
    "wheel_noise": (WheelNoise, True),
    "gyro_noise": (GyroNoise, True),
    "turn_scale": (Prior, False),
    "distance_scale": (Prior, True),
    "fix_offset": (FixOffset, True),
    "gate": (Gate, True),
    "slip": (SlipTest, False),
    "window": (Window, False),
    "encoders": (Encoders, False),
    "sensors": (SensorCalibration, False),
    "whole_log": (WholeLog, False),
}
