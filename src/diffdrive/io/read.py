"""``read_run``: the run in any file that holds one (a wheel-log table, an OptiOdom run file,
a bag), with a bag's reference topic as its ground truth."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from diffdrive.evaluation import interpolate
from diffdrive.io.logs import read_log
from diffdrive.io.run import Run
from diffdrive.io.sniff import is_bag
from diffdrive.io.tables import TableError
from diffdrive.io.trajectories import read_trajectory
from diffdrive.model import Robot

__all__ = ["read_commands", "read_run"]


def read_run(
    path: str | Path,
    time_unit: str | None = None,
    *,
    joint_topic: str = "/joint_states",
    left_joint: str | None = None,
    right_joint: str | None = None,
    reference_topic: str | None = None,
    wheel_topic: str | None = None,
    robot: Robot | None = None,
) -> Run:
    """The run in ``path``: a wheel-log table, an OptiOdom run file, or a bag.

    ``time_unit`` is the unit of a table's ``t`` (``s``, ``ms``, ``us``, ``ns``; None:
    seconds, refused when plainly not). A bag needs ``left_joint`` and ``right_joint``, the
    names of the wheel joints on ``joint_topic``, or a ``wheel_topic`` (a drive controller's
    ``Odometry``, or ``Twist`` commands: ``ros.read_wheel_motion``, through ``robot``'s
    inverse kinematics); a ``reference_topic`` of it becomes the ground truth, sampled at the
    run's times along the reference's arcs (the run is cut to the span the reference covers).
    ``TableError`` names the file, line and column of what is wrong.
    """
    if not is_bag(path):
        for name, topic in (("a reference topic", reference_topic), ("a wheel topic", wheel_topic)):
            if topic is not None:
                raise TableError(f"{path}: {name} needs a bag; this is a log file")
        return read_log(path, time_unit)
    from diffdrive.io import ros

    if wheel_topic is not None:
        if left_joint is not None or right_joint is not None:
            raise TableError(f"{path}: the wheels come from joints or from {wheel_topic}, not both")
        if robot is None:
            raise ValueError("a wheel topic needs the robot, whose inverse kinematics it takes")
        return _with_reference(
            ros.read_wheel_motion(path, wheel_topic, robot), path, reference_topic
        )
    if left_joint is None or right_joint is None:
        # What the bag has first: its JointState topic (ros names a missing one), then names.
        joints = ", ".join(ros.joint_names(path, joint_topic)) or "none"
        raise TableError(
            f"{path}: give the wheel joints by name: --joints LEFT RIGHT "
            f"(the joints on {joint_topic}: {joints})"
        )
    run = ros.read_joint_states(path, left_joint, right_joint, joint_topic)
    return _with_reference(run, path, reference_topic)


def _with_reference(run: Run, path, reference_topic: str | None) -> Run:
    """``run`` with a bag's ``reference_topic`` as its ground truth, cut to its span."""
    if reference_topic is None:
        return run
    times, poses = read_trajectory(path, topic=reference_topic)
    if np.isnan(poses[:, 2]).any():
        raise TableError(f"{path}: {reference_topic} has no heading; a reference needs one")
    inside = (run.times >= times[0]) & (run.times <= times[-1])
    if np.count_nonzero(inside) < 2:
        raise TableError(f"{path}: {reference_topic} does not span the wheels' times")
    truth = interpolate(times, poses, run.times[inside])
    return replace(run.rows(inside), truth=truth, source=f"{run.source} against {reference_topic}")


def read_commands(
    path: str | Path, robot: Robot, run: Run, topic: str | None = None
) -> tuple[np.ndarray, np.ndarray] | None:
    """The wheel velocities commanded ``(times (M,) s, velocities (M, 2) rad/s)``, each held
    from its stamp: a bag's ``geometry_msgs/Twist`` ``topic`` through ``robot``'s inverse
    kinematics (its ``vy`` unused), else ``run``'s command columns; None without either."""
    if topic is not None:
        from diffdrive import batch
        from diffdrive.io import ros

        twists = ros.read_twists(path, topic)
        v, omega = twists.twists.T
        return twists.times, batch.to_wheel_velocities(robot, np.column_stack([v, 0 * v, omega]))
    if run.commands is None:
        return None
    return run.times[:-1], run.commands[:-1]
