"""Where a command's input comes from: a file, or a topic of a ROS bag or MCAP file.

- ``wheel_log``: a ``WheelLog`` from a log file (``diffdrive.logs``) or from a bag's
  ``sensor_msgs/JointState`` topic (joints by name), optionally with a reference trajectory
  from another topic as its ground truth, sampled at the log's times along the reference's
  arcs (the log is cut to the span the reference covers).
- ``trajectory``: ``(times, poses)`` from a trajectory file (``diffdrive.trajectories``) or a
  bag topic: ``nav_msgs/Odometry``, ``sensor_msgs/NavSatFix`` (local east, north; the
  heading unknown, NaN) or ``tf:PARENT:CHILD`` (a transform chain).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from diffdrive.files import TableError
from diffdrive.logs import WheelLog, read_log

__all__ = ["is_bag", "trajectory", "wheel_log"]


def is_bag(path: str | Path) -> bool:
    """Whether ``path`` is a ROS 1 bag, an MCAP file or a ROS 2 bag folder."""
    path = Path(path)
    return path.suffix in (".bag", ".mcap") or (path / "metadata.yaml").is_file()


def wheel_log(
    path: str | Path,
    time_unit: str | None = None,
    *,
    joint_topic: str = "/joint_states",
    left_joint: str | None = None,
    right_joint: str | None = None,
    reference_topic: str | None = None,
) -> WheelLog:
    """The wheel log in ``path`` (see the module); bags need ``left_joint`` and
    ``right_joint``, the names of the wheel joints."""
    if not is_bag(path):
        if reference_topic is not None:
            raise TableError(f"{path}: a reference topic needs a bag; this is a log file")
        return read_log(path, time_unit)
    from diffdrive import ros

    if left_joint is None or right_joint is None:
        raise TableError(
            f"{path}: give the wheel joints by name: --left-joint NAME --right-joint NAME"
        )
    log = ros.read_joint_states(path, left_joint, right_joint, joint_topic)
    if reference_topic is None:
        return log
    times, poses = trajectory(path, topic=reference_topic)
    if np.isnan(poses[:, 2]).any():
        raise TableError(f"{path}: {reference_topic} has no heading; a reference needs one")
    inside = (log.times >= times[0]) & (log.times <= times[-1])
    if np.count_nonzero(inside) < 2:
        raise TableError(f"{path}: {reference_topic} does not span the joint states' times")
    from diffdrive.evaluation import interpolate

    truth = interpolate(times, poses, log.times[inside])
    return replace(log, times=log.times[inside], wheels=log.wheels[inside], truth=truth,
                   source=f"{log.source} against {reference_topic}")  # fmt: skip


def trajectory(
    path: str | Path, time_unit: str | None = None, topic: str | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """``(times (N,), poses (N, 3))`` of a trajectory file or bag topic (see the module)."""
    from diffdrive.trajectories import read_trajectory

    if not is_bag(path):
        if topic is not None:
            raise TableError(f"{path}: a topic needs a bag; this is a trajectory file")
        return read_trajectory(path, time_unit)
    from diffdrive import ros

    if topic is None:
        usable = [t.name for t in ros.topics(path) if t.msgtype in _TRAJECTORY_TYPES]
        raise TableError(
            f"{path}: give the topic of a trajectory (--topic or --truth-topic): one of "
            f"{', '.join(usable) or 'none here'}, or tf:PARENT:CHILD"
        )
    if topic.startswith("tf:"):
        frames = topic.split(":")
        if len(frames) != 3:
            raise TableError(f"a transform chain is tf:PARENT:CHILD, got {topic!r}")
        times, poses = ros.read_tf(path, frames[1], frames[2])
    else:
        kind = {t.name: t.msgtype for t in ros.topics(path)}.get(topic)
        if kind == "sensor_msgs/msg/NavSatFix":
            fixes = ros.read_navsatfix(path, topic)
            times = fixes.times
            poses = np.column_stack([fixes.positions, np.full(len(times), np.nan)])
        else:
            odometry = ros.read_odometry(path, topic)  # names the topic if it is not one
            times, poses = odometry.times, odometry.poses
    if len(times) < 2:
        raise TableError(f"{path}: {topic} needs 2 or more poses")
    return times, poses


_TRAJECTORY_TYPES = ("nav_msgs/msg/Odometry", "sensor_msgs/msg/NavSatFix")
