"""What a controller would have sent to drive a trajectory: per interval, the body twist that
joins its poses (``vx``, ``omega``) and the wheel velocities that make it (rad/s, each held
over its interval, as a log's commands are), by the robot model's inverse kinematics."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from diffdrive import batch
from diffdrive.model import Robot
from diffdrive.sensors.motion import motion_of

__all__ = ["Commands", "commands_of"]


@dataclass(frozen=True, eq=False)
class Commands:
    """``twists`` ``(B, T, 3)`` ``[vx, vy, omega]`` (the body origin's) and ``wheels``
    ``(B, T, 2)`` rad/s, each held from ``times[k]`` to ``times[k+1]``; ``times`` ``(T+1,)``."""

    times: np.ndarray
    twists: np.ndarray
    wheels: np.ndarray


def commands_of(robot: Robot, times: object, poses: object) -> Commands:
    """The commands that drive ``robot`` along the trajectory ``times``, ``poses``."""
    motion = motion_of(robot, times, poses)
    at_reference = motion.increments / motion.durations[:, None]
    wheels = batch.to_wheel_velocities(robot.equivalent, at_reference)
    return Commands(motion.times, robot.twist_from_reference(at_reference), wheels)
