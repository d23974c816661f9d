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
``turn_scale_sigma`` > 0. Every interval with a gyro reading is tested for slip; a flagged
interval's wheel turn is left out and its wheel noise inflated.

Absolute measurements. ``add_pose``, ``add_position`` and ``add_heading`` take a measurement
stamped at its
own time ``t``: the estimator keeps the last ``history`` s of wheel intervals (each with the
state at its start), applies a measurement at its stamp (splitting the interval there) and
replays the intervals after it to now. So the result does not depend on the order in which
measurements arrive. A measurement is gated: past the ``gate`` probability's chi-square
quantile it is refused and counted (``rejected``). A stamp older than the history, or more
than ``ahead`` s past the newest wheel reading, raises ``ValueError``; one up to ``ahead`` s
past it waits for the wheels. ``pose_at(t)`` gives the pose and covariance at any stamp
inside the history.

Cores. The readings, the history and the replay, and ``estimate_trajectory``'s pass over a
whole log (``_run_log``), are in C (the C core's filter and history, ``c/``, bound in
``backends/_estimator.c``) where a C compiler was found, else in their pure-Python twin
(``estimation/_estimator_python.py``, also ``_PythonPoseEstimator``); ``estimation._cores``
chooses, for Odometry's core too, and ``COMPILED`` says which.
Both run ``diffdrive.estimation.filter``'s maths, the C one mirroring it; the tests hold the
two to each other.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from diffdrive._validate import finite, settings_of
from diffdrive.backends.settings import HEADINGS, CoreSettings
from diffdrive.estimation import _estimator_python
from diffdrive.estimation import filter as ekf
from diffdrive.estimation._cores import COMPILED
from diffdrive.estimation._cores import EstimatorCore as _Core
from diffdrive.estimation.imu import mounting_yaw_row
from diffdrive.estimation.measurements import Measurement, chi2_quantile
from diffdrive.estimation.odometry import Odometry
from diffdrive.estimation.settings import OUTLIERS, EstimatorSettings
from diffdrive.model import Robot, check_robot, geometry_of
from diffdrive.sensor_noise import GyroNoise
from diffdrive.types import Pose

__all__ = ["COMPILED", "HEADINGS", "OUTLIERS", "GyroNoise", "PoseEstimator"]


if TYPE_CHECKING:  # the core's methods, as the stub and the twin declare them
    _Base = _estimator_python.EstimatorCore
else:
    _Base = object


class _EstimatorMethods(_Base):
    """PoseEstimator's methods, on whichever core it has (see ``PoseEstimator``)."""

    def __init__(
        self,
        robot: Robot,
        settings: EstimatorSettings | None = None,
        *,
        initial_pose: object = None,
        initial_covariance: object = None,
        initial_time: float | None = None,
    ) -> None:
        check_robot(robot)
        settings = settings_of(settings, EstimatorSettings)
        if settings.sensors.gyro_calibrated:
            raise ValueError(
                "a streaming estimator takes each interval's gyro angle as given, so it cannot "
                "move the gyro onto the wheels' clock or scale (SensorCalibration.gyro_offset "
                f"{settings.sensors.gyro_offset:g} s, gyro_scale {settings.sensors.gyro_scale:g}): "
                "integrate the readings of Gyro.calibrated(offset, scale), or run the whole log "
                "through estimate_trajectory"
            )
        self.robot, self.settings, self.heading = robot, settings, settings.heading
        encoders = settings.encoders
        wheels = Odometry(
            robot,
            settings.method,
            ticks_per_revolution=encoders.ticks_per_revolution,
            counter_bits=encoders.counter_bits,
            max_wheel_speed=encoders.max_wheel_speed,
        )
        if initial_time is not None:
            wheels.update_increments(0.0, 0.0, finite("initial_time", initial_time))
        self._wheels = wheels
        x, P = start_state(robot, settings, initial_pose, initial_covariance)
        self.config = core_settings(robot, settings, x, P)
        super().__init__(wheels, self.config)

    # -- what it knows --------------------------------------------------------------------

    @property
    def time(self) -> float | None:
        """The time of the newest wheel reading, s; None before the first."""
        return self._wheels.time

    @property
    def state(self) -> np.ndarray:
        """``(x, y, theta, bias, turn_scale, distance_scale, offset_x, offset_y)`` of the
        equivalent drive's reference point (``diffdrive.estimation.filter``)."""
        return np.array(self._state_now())

    @property
    def state_covariance(self) -> np.ndarray:
        """The state's covariance, 8x8."""
        return np.array(self._covariance_now()).reshape(ekf.N, ekf.N)

    @property
    def pose(self) -> Pose:
        """The body origin's pose now."""
        return _body_pose(self._state_now(), self.robot)

    @property
    def covariance(self) -> np.ndarray:
        """The body origin's pose covariance now, 3x3 over ``(x, y, theta)``."""
        return body_covariances(self.state, self.state_covariance, self.robot)

    @property
    def bias(self) -> float:
        """The gyro bias estimate, rad/s."""
        return self._state_now()[ekf.BIAS]

    @property
    def turn_scale(self) -> float:
        """The turn scale estimate: the robot's turn per radian of the wheels' turn."""
        return self._state_now()[ekf.SCALE]

    @property
    def distance_scale(self) -> float:
        """The distance scale estimate: the robot's travel per metre of the wheels'."""
        return self._state_now()[ekf.DISTANCE]

    @property
    def fix_offset(self) -> np.ndarray:
        """The position fixes' offset estimate ``(2,)``, m (world frame)."""
        return np.array(self._state_now()[ekf.OFFSET : ekf.OFFSET + 2])

    @property
    def accepted(self) -> int:
        """Absolute measurements taken (as the history now stands)."""
        return self._counts()[0]

    @property
    def rejected(self) -> int:
        """Absolute measurements the gate refused (as the history now stands)."""
        return self._counts()[1]

    @property
    def slip(self) -> bool:
        """Whether the last wheel interval was flagged as slipping."""
        return self._slip()[0]

    @property
    def slip_score(self) -> float:
        """The last interval's slip test score (chi-square, one degree of freedom)."""
        return self._slip()[1]

    @property
    def command_score(self) -> float:
        """The last interval's command test score (chi-square, two degrees of freedom)."""
        return self._slip()[2]

    @property
    def history_start(self) -> float | None:
        """The oldest stamp a measurement may have now, s."""
        start = self._history_start()
        return None if math.isnan(start) else start

    def pose_at(self, t: float) -> tuple[Pose, np.ndarray]:
        """The body origin's pose and 3x3 covariance at stamp ``t`` (s) inside the history,
        with every measurement stamped up to ``t``."""
        t = finite("t", t)
        start, now = self.history_start, self.time
        if start is None or now is None:
            raise ValueError(f"no pose at t = {t!r} s: the estimator has had no wheel reading")
        if not start <= t <= now:
            raise ValueError(f"t = {t!r} s lies outside the history [{start!r}, {now!r}] s")
        x, P = self._pose_at(t)
        state, covariance = np.array(x), np.array(P).reshape(ekf.N, ekf.N)
        return _body_pose(state, self.robot), body_covariances(state, covariance, self.robot)

    # -- absolute measurements ------------------------------------------------------------

    def add_pose(self, t, pose, covariance, lever_arm=None) -> bool:
        """A pose ``(x, y, theta)`` (m, m, rad) measured at stamp ``t`` (s), ``covariance`` 3x3
        or 3 standard deviations; True if the gate took it (False also while it waits for
        the wheels)."""
        if self.settings.sensors.measurements_calibrated:  # moved by the calibration found
            return self.add(Measurement.make("pose", t, pose, covariance, lever_arm))
        taken = self._add_fast(0, t, pose, covariance, lever_arm)
        if taken is None:  # anything but plain numbers: checked, and named if wrong
            taken = self._add(Measurement.make("pose", t, pose, covariance, lever_arm))
        return taken

    def add_position(self, t, position, covariance, lever_arm=None) -> bool:
        """A position ``(x, y)`` (m) measured at stamp ``t`` (s), ``covariance`` 2x2, 2 or 1
        standard deviations; True if the gate took it."""
        if self.settings.sensors.measurements_calibrated:
            return self.add(Measurement.make("position", t, position, covariance, lever_arm))
        taken = self._add_fast(1, t, position, covariance, lever_arm)
        if taken is None:
            taken = self._add(Measurement.make("position", t, position, covariance, lever_arm))
        return taken

    def add_heading(self, t, heading, sigma) -> bool:
        """A heading (rad) measured at stamp ``t`` (s) with standard deviation ``sigma``
        (rad); True if the gate took it."""
        if self.settings.sensors.measurements_calibrated:
            return self.add(Measurement.make("heading", t, [heading], sigma))
        taken = self._add_fast(2, t, heading, sigma, None)
        if taken is None:
            taken = self._add(Measurement.make("heading", t, [heading], sigma))
        return taken

    def add(self, measurement: Measurement) -> bool:
        """A ``Measurement`` made elsewhere (``Measurement.make``)."""
        if not isinstance(measurement, Measurement):
            raise TypeError(f"measurement must be a Measurement, got {type(measurement).__name__}")
        return self._add(self.settings.sensors.placed(measurement))

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.robot!r}, {self.heading!r}, pose={self.pose!r})"


class PoseEstimator(_EstimatorMethods, _Core):
    """Wheels, gyro and absolute measurements in one extended Kalman filter (see the module).

    ``robot``: any model (its equivalent drive runs the filter; poses and covariances are
    the body origin's). ``settings``: an ``EstimatorSettings`` (the heading's source, the
    sensors' noise, the estimated states and their priors, the gate, the slip test, the
    window, the integration, the mounting and the encoders; default ``EstimatorSettings()``).
    ``initial_pose`` and ``initial_covariance`` (3x3): the start; ``initial_time`` (s) its
    time, else the first ticks or positions reading's.
    """


class _PythonPoseEstimator(_EstimatorMethods, _estimator_python.EstimatorCore):
    """``PoseEstimator`` on the pure-Python core, whether or not the C core was built: the
    same results, slower: the reference the tests hold the C core to."""


def start_state(
    robot: Robot, settings: EstimatorSettings, pose: object, covariance: object
) -> tuple[np.ndarray, np.ndarray]:
    """The filter's state ``(8,)`` and covariance ``(8, 8)`` at the start: the body pose
    ``pose`` with its 3x3 ``covariance`` moved to the reference point, and the other states at
    ``settings``' starts with their priors' variances."""
    start = Pose() if pose is None else Pose.coerce(pose, "initial_pose")
    matrix = np.zeros((3, 3)) if covariance is None else np.asarray(covariance, dtype=float)
    if matrix.shape != (3, 3) or not np.all(np.isfinite(matrix)):
        raise ValueError(f"initial_covariance must be a finite 3x3, got shape {matrix.shape}")
    if not np.allclose(matrix, matrix.T) or np.linalg.eigvalsh(matrix).min() < -1e-12 * max(
        1.0, np.abs(matrix).max()
    ):
        raise ValueError("initial_covariance must be symmetric positive semi-definite")
    moved = robot.covariance_to_reference(start.theta, matrix)
    start = robot.to_reference(start)
    turn, distance, offset = settings.turn_scale, settings.distance, settings.offset
    x = np.array(
        [start.x, start.y, start.theta, settings.bias_start, turn.start, distance.start, 0, 0]
    )
    P = np.zeros((ekf.N, ekf.N))
    P[:3, :3] = moved
    fused = settings.heading == "fused"
    P[ekf.BIAS, ekf.BIAS] = settings.gyro.initial_bias_sigma**2 if fused else 0.0
    P[ekf.SCALE, ekf.SCALE] = turn.sigma * turn.sigma
    P[ekf.DISTANCE, ekf.DISTANCE] = distance.sigma * distance.sigma
    P[ekf.OFFSET, ekf.OFFSET] = P[ekf.OFFSET + 1, ekf.OFFSET + 1] = offset.sigma**2
    return x, P


def core_settings(
    robot: Robot, settings: EstimatorSettings, x: np.ndarray, P: np.ndarray
) -> CoreSettings:
    """What the estimator's core is built from: ``settings`` on ``robot``'s equivalent drive,
    from state ``x`` ``(8,)`` with covariance ``P`` ``(8, 8)``."""
    gyro, gate, slip = settings.gyro, settings.gating, settings.slip
    arw, rrw = gyro.angle_random_walk, gyro.rate_random_walk
    probability = gate.probability
    return CoreSettings(
        drive=geometry_of(robot),
        method=settings.method,
        heading=settings.heading,
        k=(settings.wheels.left, settings.wheels.right),
        # weighed against a gyro, an interval's rounding counts; a wheels' heading sums the
        # counts, whose roundings cancel but for the last
        wheel_floor=settings.encoders.wheel_floor if settings.heading != "wheels" else 0.0,
        arw2=arw * arw,
        rrw2=rrw * rrw,
        estimate_bias=settings.heading == "fused",
        estimate_scale=settings.turn_scale.estimated,
        estimate_distance=settings.distance.estimated,
        estimate_offset=settings.offset.estimated,
        offset_rate2=settings.offset.rate**2,
        slip_threshold=slip.threshold,
        slip_inflation=slip.inflation,
        command_sigma=slip.command_sigma,
        gates=tuple(chi2_quantile(probability, size) for size in (1, 2, 3)),  # type: ignore[arg-type]
        inflate=gate.outliers == "inflate",
        offset=robot.reference_offset,
        history=settings.window.history,
        ahead=settings.window.ahead,
        mounting=_three(mounting_yaw_row(settings.mounting)),
        state=tuple(x.tolist()),
        covariance=tuple(P.ravel().tolist()),
    )


def _three(row: np.ndarray) -> tuple[float, float, float]:
    return float(row[0]), float(row[1]), float(row[2])


def body_poses(states: np.ndarray, robot: Robot) -> np.ndarray:
    """The body origin's poses ``(..., 3)`` from states ``(..., 8)`` of ``robot``'s equivalent
    drive's reference point (``Robot.from_reference``)."""
    return np.array(robot.from_reference(np.asarray(states, dtype=float)[..., :3]), dtype=float)


def body_covariances(states: np.ndarray, covariances: np.ndarray, robot: Robot) -> np.ndarray:
    """The body origin's pose covariances ``(..., 3, 3)`` from states ``(..., 8)`` and their
    covariances ``(..., 8, 8)`` (see ``body_poses``): the shift's Jacobian applied."""
    block = np.asarray(covariances, dtype=float)[..., :3, :3]
    return robot.covariance_from_reference(np.asarray(states)[..., 2], block)


def _body_pose(x: Sequence[float] | np.ndarray, robot: Robot) -> Pose:
    return Pose(*body_poses(np.asarray(x, dtype=float), robot).tolist())
