"""Streaming odometry: encoder readings in, pose, velocity and covariance out (seed 002).

``Odometry`` is the object a robot keeps in its control loop. Its update methods and state are
in C (``diffdrive._odometry``); this class adds the checked constructor and the views.

Rules, stated once:

- Readings. ``update_ticks`` takes absolute counter readings (ints, or whole floats): the first
  only sets the reference, so nothing jumps at start-up; with ``counter_bits`` (2 to 64) the
  change goes through at most one roll-over of a signed or unsigned counter of that width
  (``diffdrive.encoders``). ``update_positions`` takes accumulated wheel angles (rad), first
  reading a reference too. ``update_increments`` takes the angles turned since the last update
  (rad); ``update_velocities`` rates (rad/s) held over ``dt``.
- Time. ``t`` (s) is optional. With it, time must not go backwards, nor stand still while the
  wheels move; ``max_wheel_speed`` (rad/s) is checked; and the velocity window fills. An update
  without ``t`` leaves the clock unknown until the next time stamp. ``update_velocities``
  advances the clock by ``dt`` (from 0 s if there was none).
- Faults. A reading that is not finite, a time that goes backwards or stands still, or a jump
  beyond ``max_wheel_speed`` (a glitch, or a roll-over with the wrong ``counter_bits``) raises
  ``ValueError`` that names it, and leaves the state exactly as before the call.
- Uncertainty (Siegwart, Nourbakhsh and Scaramuzza, *Introduction to Autonomous Mobile Robots*,
  2nd ed., 2011, sec. 5.2.4, eq. 5.9): in each update, the travel of each wheel (m) has a
  variance ``k |ds|`` with the wheel's ``k`` of ``wheel_noise`` (a ``WheelNoise``; by default
  ``diffdrive.sensor_noise.DEFAULT``, 1e-4 m both), independent. ``k`` (m) scales the
  *variance*, not the standard deviation: variances of independent pieces add, so the
  covariance at the end of a path does not depend on how finely the updates slice it (with
  ``k`` on the standard deviation it would shrink as the update rate grows). The pose covariance
  moves through each update with the Jacobians of the chosen method (``jacobians``).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Literal

import numpy as np

from diffdrive._step import wheel_move
from diffdrive._validate import finite, floats, positive
from diffdrive.encoders import check_counter_bits
from diffdrive.estimation._cores import COMPILED
from diffdrive.estimation._cores import OdometryCore as _Core
from diffdrive.integrate import METHODS, Method, check_method
from diffdrive.model import Robot, check_robot, geometry_of
from diffdrive.types import Pose, Twist, WheelVelocities

if TYPE_CHECKING:
    from diffdrive.io.run import Run
    from diffdrive.sensor_noise import WheelNoiseLike

__all__ = [
    "COMPILED",
    "UPDATE_KINDS",
    "Odometry",
    "RefusedUpdateError",
    "odometry_of_run",
]


UpdateKind = Literal["ticks", "positions", "increments", "velocities"]
UPDATE_KINDS: tuple[UpdateKind, ...] = ("ticks", "positions", "increments", "velocities")
"""What an odometry update reads: counter ``"ticks"``, accumulated wheel ``"positions"`` (rad),
``"increments"`` (rad) or ``"velocities"`` (rad/s) held over a step."""


class RefusedUpdateError(ValueError):
    """An update of ``Odometry.update_arrays`` refused: ``row`` is its index."""

    def __init__(self, row: int, message: str) -> None:
        super().__init__(f"row {row}: {message}")
        self.row = row
        self.reason = message


# The update that takes each kind of a Run's wheel readings.
UPDATE_OF_RUN: dict[str, UpdateKind] = {
    "ticks": "ticks",
    "angle": "positions",
    "velocity": "velocities",
}


if TYPE_CHECKING:  # the core's methods, as the stub and the twin declare them
    from diffdrive.estimation._odometry_python import OdometryCore as _Base
else:
    _Base = object


class _OdometryMethods(_Base):
    """Odometry's methods, on whichever core it has (see ``Odometry``)."""

    def __init__(
        self,
        robot: Robot,
        method: Method = "exact",
        initial_pose: Pose | None = None,
        ticks_per_revolution: float | None = None,
        counter_bits: int | None = None,
        *,
        max_wheel_speed: float | None = None,
        wheel_noise: WheelNoiseLike | None = None,
        initial_covariance: object = None,
        velocity_window: float = 0.1,
    ) -> None:
        check_robot(robot)
        check_method(method)
        counter_bits = check_counter_bits(counter_bits)
        counts = 0.0
        if ticks_per_revolution is not None:
            counts = positive("ticks_per_revolution", ticks_per_revolution)
            if not math.isfinite(2.0 * math.pi / counts):
                raise ValueError(
                    f"ticks_per_revolution must give a finite angle per count, got "
                    f"{ticks_per_revolution!r}"
                )
        speed_limit = math.inf
        if max_wheel_speed is not None:
            speed_limit = positive("max_wheel_speed", max_wheel_speed)
        # Here, not at import: ``import diffdrive`` loads the core only (bench_import).
        from diffdrive.backends.settings import OdometrySettings
        from diffdrive.sensor_noise import DEFAULT, WheelNoise

        self.wheel_noise = DEFAULT if wheel_noise is None else WheelNoise.coerce(wheel_noise)
        self.robot = robot
        self.method: Method = method
        self.ticks_per_revolution = ticks_per_revolution
        self.counter_bits = counter_bits
        # The core runs the equivalent drive, whose reference point lies ``_offset`` m left of
        # the body origin (a skid-steer robot's ICR midpoint); poses and covariances move back.
        self._offset = robot.reference_offset
        self.settings = OdometrySettings(
            drive=geometry_of(robot),
            method_code=METHODS.index(method),
            ticks_per_revolution=counts,
            max_wheel_speed=speed_limit,
            counter_bits=counter_bits or 0,
            k=(self.wheel_noise.left, self.wheel_noise.right),
            velocity_window=positive("velocity_window", velocity_window),
        )
        super().__init__(self.settings)
        self.reset(Pose() if initial_pose is None else initial_pose, initial_covariance)

    @property
    def pose(self) -> Pose:
        """The pose now; ``theta`` unwrapped (rad)."""
        x, y, theta, _, _ = self._state()
        return self.robot.from_reference(Pose(x, y, theta))

    @property
    def distance(self) -> float:
        """Distance travelled by the reference point since the start or the last reset, m
        (for a ``SkidSteer``, by the midpoint of its ICRs)."""
        return self._state()[3]

    @property
    def time(self) -> float | None:
        """The time of the last update, s; None while the clock is unknown."""
        t = self._state()[4]
        return None if math.isnan(t) else t

    @property
    def covariance(self) -> np.ndarray:
        """The pose covariance, 3x3 over ``(x, y, theta)``: m^2, m rad, rad^2."""
        covariance = np.array(self._covariance()).reshape(3, 3)
        return self.robot.covariance_from_reference(self._state()[2], covariance)

    @property
    def wheel_velocities(self) -> WheelVelocities:
        """Mean wheel velocities (rad/s) over the last ``velocity_window`` s of updates.

        Needs two time-stamped samples in the window (the reference reading counts). The
        window keeps samples at least ``velocity_window / 1024`` s apart, so its memory is
        bounded at any update rate and its span is the window to within that.
        """
        window = self._window_velocities()
        if window is None:
            raise ValueError(
                "a velocity needs two time-stamped updates: give t to the updates "
                "(update_velocities keeps its own clock)"
            )
        return WheelVelocities(window[0], window[1])

    @property
    def twist(self) -> Twist:
        """The body twist from the mean wheel velocities over the velocity window."""
        return self.robot.to_twist(self.wheel_velocities)

    def reset(self, pose: Pose | None = None, covariance: object = None) -> None:
        """Put the robot at ``pose`` (default the origin) with ``covariance`` (default zero).

        The distance restarts from 0. The counter references, the clock and the velocity
        window are kept, so the next reading moves on from here without a jump.
        """
        pose = Pose() if pose is None else Pose.coerce(pose, "pose")
        matrix = np.zeros((3, 3)) if covariance is None else floats("covariance", covariance)
        if matrix.shape != (3, 3):
            raise ValueError(f"covariance must be 3x3, got shape {matrix.shape}")
        if not np.all(np.isfinite(matrix)) or not np.allclose(matrix, matrix.T):
            raise ValueError("covariance must be finite and symmetric")
        if np.linalg.eigvalsh(matrix).min() < -1e-12 * max(1.0, np.abs(matrix).max()):
            raise ValueError("covariance must be positive semi-definite")
        if self._offset:  # to the equivalent drive's reference point
            matrix = self.robot.covariance_to_reference(pose.theta, matrix)
            pose = self.robot.to_reference(pose)
        self._set_pose(pose.x, pose.y, pose.theta, tuple(matrix.ravel().tolist()))

    def update_arrays(
        self,
        kind: UpdateKind,
        left: object,
        right: object,
        t: object = None,
        covariance: bool = False,
        *,
        dt: object = None,
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """The updates of a whole log at C speed: row k is ``update_<kind>(left[k], right[k],
        t[k])`` (``"velocities"``: ``update_velocities(left[k], right[k], dt[k])``), checked
        exactly as one call. ``t`` (s) are the rows' time stamps (None: none); ``dt`` (s) how
        long each row's velocities are held, for ``"velocities"`` only.

        Returns the pose after each row ``(n, 3)`` and, if ``covariance``, the covariance after
        each row ``(n, 3, 3)``. A refused row raises ``RefusedUpdateError`` (a ``ValueError``) with
        its index in ``row``; the rows before it stay applied.
        """
        if kind not in UPDATE_KINDS:
            raise ValueError(f"kind must be one of {', '.join(UPDATE_KINDS)}, got {kind!r}")
        rows = [np.asarray(values).tolist() for values in (left, right)]
        if len(rows[0]) != len(rows[1]):
            raise ValueError(f"left and right differ in length: {len(rows[0])}, {len(rows[1])}")
        name, third = ("dt", dt) if kind == "velocities" else ("t", t)
        wrong, given = ("t", t) if kind == "velocities" else ("dt", dt)
        if given is not None:
            raise ValueError(f"{kind} updates take {name}, not {wrong} (s)")
        thirds = [None] * len(rows[0]) if third is None else np.asarray(third).tolist()
        if len(thirds) != len(rows[0]):
            raise ValueError(f"{name} must have {len(rows[0])} values, got {len(thirds)}")
        poses = np.empty((len(thirds), 3))
        covariances = np.empty((len(thirds), 3, 3)) if covariance else None
        refused = self._run(UPDATE_KINDS.index(kind), rows[0], rows[1], thirds, poses, covariances)
        if refused is not None:
            raise RefusedUpdateError(*refused)
        if self._offset:
            if covariances is not None:
                covariances = self.robot.covariance_from_reference(poses[:, 2], covariances)
            poses = self.robot.from_reference(poses)
        return poses, covariances

    def jacobians(self, left: float, right: float) -> tuple[np.ndarray, np.ndarray]:
        """The Jacobians of one update from the current pose, for an EKF.

        For wheel-angle increments ``left``, ``right`` (rad): the derivative of the new pose
        with respect to the current pose (3x3) and with respect to the increments (3x2,
        columns ``[left, right]``), for this odometry's method.
        """
        left, right = finite("left", left), finite("right", right)
        by_pose, by_wheels = self._jacobians(left, right)
        pose_jacobian = np.array(by_pose).reshape(3, 3)
        wheel_jacobian = np.array(by_wheels).reshape(3, 2)
        if self._offset:  # through the equivalent drive, and back
            theta = self._state()[2]
            turn = wheel_move(*geometry_of(self.robot), left, right)[2]
            back = self.robot.jacobian_from_reference(theta + turn)
            pose_jacobian = back @ pose_jacobian @ self.robot.jacobian_to_reference(theta)
            wheel_jacobian = back @ wheel_jacobian
        return pose_jacobian, wheel_jacobian

    def __repr__(self) -> str:
        return f"Odometry({self.robot!r}, method={self.method!r}, pose={self.pose!r})"


def odometry_of_run(
    robot: Robot,
    run: Run,
    method: Method = "exact",
    *,
    ticks_per_revolution: float | None = None,
    counter_bits: int | None = None,
    max_wheel_speed: float | None = None,
    wheel_noise: WheelNoiseLike | None = None,
    covariance: bool = False,
) -> tuple[np.ndarray, np.ndarray | None]:
    """``Odometry`` over a whole ``Run``, from its first ground-truth pose (else the origin):
    the pose after each row ``(T+1, 3)`` and, if ``covariance``, the covariances ``(T+1, 3, 3)``.

    Ticks use ``ticks_per_revolution`` (else the run's own) and ``counter_bits``; velocities
    are held from each row to the next (the first row is the start). A refused row raises
    ``TableError`` naming its file and line.
    """
    from diffdrive.errors import TableError

    kind = UPDATE_OF_RUN[run.kind]
    ticks = ticks_per_revolution or run.ticks_per_revolution
    odometry = Odometry(
        robot,
        method,
        Pose(*run.start_pose()),
        ticks if kind == "ticks" else None,
        counter_bits,
        max_wheel_speed=max_wheel_speed,
        wheel_noise=wheel_noise,
    )
    times, wheels = run.times, run.wheels
    first = 1 if kind == "velocities" else 0  # a velocity is held until the next row
    stamps = {"dt": np.diff(times)} if first else {"t": times}
    rows = wheels[:-1] if first else wheels
    try:
        poses, covariances = odometry.update_arrays(
            kind, rows[:, 0], rows[:, 1], covariance=covariance, **stamps
        )
    except RefusedUpdateError as refused:
        raise TableError(f"{run.where(refused.row + first)}: {refused.reason}") from None
    if first:
        poses = np.vstack([run.start_pose()[None, :], poses])
        if covariances is not None:
            covariances = np.vstack([np.zeros((1, 3, 3)), covariances])
    return poses, covariances


class Odometry(_OdometryMethods, _Core):
    """Dead reckoning from wheel encoders, one update at a time.

    ``robot`` gives the geometry; ``method`` is ``"euler"``, ``"rk2"`` or ``"exact"``;
    ``initial_pose`` is where it starts (default the origin). ``ticks_per_revolution`` (counts
    per wheel revolution) is needed for ``update_ticks``; ``counter_bits`` (2 to 64) is the
    width of the encoder counters, None for counters that never roll over.
    ``max_wheel_speed`` (rad/s, default none) refuses jumps; ``wheel_noise`` is the covariance
    model's (a ``WheelNoise``, a number ``k`` (m) for both wheels or a pair; None, the
    default: ``diffdrive.sensor_noise.DEFAULT``); ``initial_covariance`` is 3x3 (default zero);
    ``velocity_window`` (s) is the span over which ``twist`` averages.
    """


def __getattr__(name: str) -> type:
    """``_PythonOdometry``, made when first reached: the twin's module loads only then."""
    if name != "_PythonOdometry":
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    from diffdrive.estimation._odometry_python import OdometryCore as PythonCore

    class _PythonOdometry(_OdometryMethods, PythonCore):
        """``Odometry`` on the pure-Python core, whether or not the C core was built: the
        same results, slower (for tests, and where a C compiler never ran)."""

    _PythonOdometry.__module__, _PythonOdometry.__qualname__ = __name__, "_PythonOdometry"
    globals()["_PythonOdometry"] = _PythonOdometry
    return _PythonOdometry
