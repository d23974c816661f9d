"""Open-loop odometry: the path a robot will drive when its commands go through the limits.

Each command, a twist ``(v, omega)`` or wheel velocities ``(left, right)``, goes through a
``Limiter``, becomes wheel velocities, is desaturated to ``max_wheel_velocity`` (keeping the
curvature unless told otherwise) and is held for ``dt``. ``OpenLoopOdometry`` does this one
command at a time, as a controller would (ROS's ``open_loop`` mode); ``drive_commands`` does it
for a whole command sequence and returns the ``Trajectory``.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from diffdrive._validate import positive
from diffdrive.batch.kinematics import to_wheel_velocities
from diffdrive.control.commands import Keep, desaturate
from diffdrive.control.limiter import Limiter
from diffdrive.estimation.odometry import Odometry
from diffdrive.integrate import Method
from diffdrive.model import DiffDrive
from diffdrive.simulation import simulate
from diffdrive.trajectory import Trajectory
from diffdrive.types import Pose, WheelVelocities

__all__ = ["CommandKind", "OpenLoopOdometry", "drive_commands"]

CommandKind = Literal["twist", "wheels"]


class _CommandPath:
    """Commands to held wheel velocities: limiter, conversion, desaturation."""

    def __init__(
        self,
        robot: DiffDrive,
        limiter: Limiter,
        kind: CommandKind,
        max_wheel_velocity: float | None,
        keep: Keep,
    ) -> None:
        if kind not in ("twist", "wheels"):
            raise ValueError(f"kind must be 'twist' or 'wheels', got {kind!r}")
        if len(limiter.limits) != 2:
            raise ValueError(f"the limiter must have 2 channels, got {len(limiter.limits)}")
        if max_wheel_velocity is not None:
            desaturate(WheelVelocities(0.0, 0.0), max_wheel_velocity, keep, robot)  # checks
        self.robot, self.limiter, self.kind = robot, limiter, kind
        self.max_wheel_velocity, self.keep = max_wheel_velocity, keep

    def wheels(self, command: object, dt: float) -> np.ndarray:
        """The wheel velocities (rad/s) held over the next ``dt`` s for ``command``."""
        wheels, planned = self.plan(command, dt)
        self.limiter._commit(planned)
        return wheels

    def plan(self, command: object, dt: float):
        """The wheel velocities for ``command`` and the limiter's planned state, which the
        caller commits once everything after the limiter has accepted them."""
        planned = self.limiter._plan(command, dt)
        limited = planned.value
        if self.kind == "twist":
            with np.errstate(over="ignore", invalid="ignore"):
                twist = np.array([limited[0], 0.0, limited[1]])
                limited = to_wheel_velocities(self.robot, twist)
            if not np.all(np.isfinite(limited)):
                raise ValueError(
                    f"the limited twist {planned.value.tolist()} needs wheel velocities beyond "
                    "the largest float; refused, nothing changed"
                )
        if self.max_wheel_velocity is not None:
            limited = desaturate(limited, self.max_wheel_velocity, self.keep, self.robot)
        return limited, planned


class OpenLoopOdometry:
    """Integrates limited commands into the pose the robot will reach.

    ``kind`` says what ``update`` takes: ``"twist"`` ``(v, omega)`` in m/s and rad/s, for a
    ``Limiter.for_twist``, or ``"wheels"`` ``(left, right)`` in rad/s. ``max_wheel_velocity``
    (rad/s, default none) desaturates the wheels, keeping ``keep``.
    """

    def __init__(
        self,
        robot: DiffDrive,
        limiter: Limiter,
        kind: CommandKind = "twist",
        *,
        max_wheel_velocity: float | None = None,
        keep: Keep = "curvature",
        method: Method = "exact",
        initial_pose: Pose | None = None,
    ) -> None:
        self._path = _CommandPath(robot, limiter, kind, max_wheel_velocity, keep)
        self.odometry = Odometry(robot, method, initial_pose)

    def update(self, command: object, dt: float) -> WheelVelocities:
        """Take ``command`` (None: no new command) and drive ``dt`` s; the wheels applied.

        A refused update (a bad command, or wheel travel the odometry refuses) changes
        neither the limiter nor the pose: the limiter's step is committed only after the
        odometry has accepted it.
        """
        wheels, planned = self._path.plan(command, dt)
        self.odometry.update_velocities(float(wheels[0]), float(wheels[1]), dt)
        self._path.limiter._commit(planned)
        return WheelVelocities(float(wheels[0]), float(wheels[1]))

    @property
    def pose(self) -> Pose:
        """Where the commands have taken the robot."""
        return self.odometry.pose


def drive_commands(
    robot: DiffDrive,
    commands: object,
    dt: float,
    limiter: Limiter,
    kind: CommandKind = "twist",
    *,
    max_wheel_velocity: float | None = None,
    keep: Keep = "curvature",
    method: Method = "exact",
    initial_pose: object = None,
) -> Trajectory:
    """The trajectory of a command sequence ``(T, 2)``, one command every ``dt`` s, limited.

    The limiter's state moves on through the sequence (start it from rest with ``reset``).
    Rows of NaN mean "no new command" that cycle, for the timeout.
    """
    dt = positive("dt", dt)
    try:
        sequence = np.asarray(commands, dtype=float)
    except OverflowError:
        raise ValueError("commands must be finite, got an integer too large for a float") from None
    if sequence.ndim != 2 or sequence.shape[1] != 2:
        raise ValueError(f"commands must have shape (T, 2), got {sequence.shape}")
    path = _CommandPath(robot, limiter, kind, max_wheel_velocity, keep)
    missing = np.isnan(sequence).all(axis=1)
    partly = np.isnan(sequence).any(axis=1) & ~missing
    if partly.any() or np.isinf(sequence).any():
        row = int(np.argmax(partly | np.isinf(sequence).any(axis=1)))
        raise ValueError(f"commands row {row} is not finite: {sequence[row].tolist()}")
    wheels = np.array(
        [path.wheels(None if gap else row, dt) for row, gap in zip(sequence, missing, strict=True)]
    )
    return simulate(robot, wheels, dt=dt, initial_pose=initial_pose, method=method)
