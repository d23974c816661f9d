"""Writing odometry to MCAP files and ROS 2 bags with ``rosbags`` (see the package)."""

from __future__ import annotations

import math
import os
import shutil
import tempfile
from pathlib import Path
from typing import Literal

import numpy as np

from diffdrive.io.tables import TableError

__all__ = ["BAG_FORMATS", "write_odometry"]

BagFormat = Literal["mcap", "ros2"]
BAG_FORMATS: tuple[BagFormat, ...] = ("mcap", "ros2")
# z, roll and pitch are not estimated by planar odometry: their variances say "unknown", as
# ROS's diff_drive_controller configures them by default.
_UNESTIMATED_VARIANCE = 1e6
_PLANAR = (0, 1, 5)  # x, y, yaw in the 6x6 (x, y, z, roll, pitch, yaw) covariance


def write_odometry(
    path: str | Path,
    times: object,
    poses: object,
    covariances: object = None,
    twists: object = None,
    *,
    format: BagFormat | None = None,
    topic: str = "/odom",
    frame: str = "odom",
    child_frame: str = "base_link",
    tf: bool = True,
) -> Path:
    """Write poses ``(N, 3)`` at ``times`` ``(N,)`` (s, >= 0) as ``nav_msgs/Odometry`` on
    ``topic``, and ``frame -> child_frame`` on ``/tf`` when ``tf``.

    ``covariances`` ``(N, 3, 3)`` over ``(x, y, theta)`` fill the pose covariance (z, roll and
    pitch get 1e6: not estimated); ``twists`` ``(N, 3)`` ``[vx, vy, omega]`` the twist (its
    covariance stays zero: unknown). ``format`` is ``"mcap"`` (one MCAP file, what Foxglove
    opens) or ``"ros2"`` (a ROS 2 bag folder, for ``ros2 bag play``); default: ``mcap`` for a
    name ending in ``.mcap``, else ``ros2``. The file or folder appears whole or not at all; an
    existing folder is not replaced.
    """
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    path = Path(path)
    format = format or ("mcap" if path.suffix == ".mcap" else "ros2")
    if format not in BAG_FORMATS:
        raise ValueError(f"format must be one of {', '.join(BAG_FORMATS)}, got {format!r}")
    times, poses, covariances, twists = _checked(times, poses, covariances, twists)
    if not path.parent.is_dir():
        raise TableError(f"cannot write {path}: the folder {path.parent} does not exist")
    if format == "ros2" and path.exists():
        raise TableError(f"cannot write {path}: it exists (a ROS 2 bag is a new folder)")
    store = get_typestore(Stores.ROS2_HUMBLE)
    plugin = StoragePlugin.MCAP if format == "mcap" else StoragePlugin.SQLITE3
    scratch = Path(tempfile.mkdtemp(dir=path.parent, prefix=f".{path.name}."))
    try:
        bag = scratch / path.stem
        with Writer(bag, version=8, storage_plugin=plugin) as writer:
            odometry = writer.add_connection(topic, "nav_msgs/msg/Odometry", typestore=store)
            transforms = writer.add_connection("/tf", "tf2_msgs/msg/TFMessage", typestore=store)
            for k in range(len(times)):
                stamp = _stamp(store, times[k])
                nanoseconds = stamp.sec * 1_000_000_000 + stamp.nanosec
                message = _odometry(
                    store, stamp, frame, child_frame, poses[k], covariances[k], twists[k]
                )
                writer.write(
                    odometry, nanoseconds, store.serialize_cdr(message, message.__msgtype__)
                )
                if tf:
                    message = _transform(store, stamp, frame, child_frame, poses[k])
                    writer.write(
                        transforms, nanoseconds, store.serialize_cdr(message, message.__msgtype__)
                    )
        if format == "mcap":
            os.replace(next(bag.glob("*.mcap")), path)
        else:
            os.rename(bag, path)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    return path


def _checked(
    times: object, poses: object, covariances: object, twists: object
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    times = np.asarray(times, dtype=float)
    poses = np.asarray(poses, dtype=float)
    if times.ndim != 1 or poses.shape != (len(times), 3) or len(times) == 0:
        raise ValueError(
            f"times (N,) and poses (N, 3) must match, got {times.shape}, {poses.shape}"
        )
    covariances = (
        np.zeros((len(times), 3, 3))
        if covariances is None
        else np.asarray(covariances, dtype=float)
    )
    twists = np.zeros((len(times), 3)) if twists is None else np.asarray(twists, dtype=float)
    if covariances.shape != (len(times), 3, 3) or twists.shape != (len(times), 3):
        raise ValueError(
            f"covariances must be ({len(times)}, 3, 3) and twists ({len(times)}, 3), got "
            f"{covariances.shape} and {twists.shape}"
        )
    for name, array in (("times", times), ("poses", poses), ("covariances", covariances)):
        if not np.all(np.isfinite(array)):
            raise ValueError(f"{name} must be finite")
    if times.min() < 0 or np.any(np.diff(times) <= 0):
        raise ValueError("times must be >= 0 (ROS time) and increase")
    return times, poses, covariances, np.nan_to_num(twists)


def _stamp(store, seconds: float):
    Time = store.types["builtin_interfaces/msg/Time"]
    whole = math.floor(seconds)
    # The fraction apart: seconds * 1e9 would round to 256 ns at stamps since 1970.
    nanoseconds = whole * 1_000_000_000 + round((seconds - whole) * 1e9)
    return Time(sec=nanoseconds // 1_000_000_000, nanosec=nanoseconds % 1_000_000_000)


def _quaternion(store, yaw: float):
    Quaternion = store.types["geometry_msgs/msg/Quaternion"]
    return Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))


def _odometry(store, stamp, frame, child_frame, pose, covariance, twist):
    t = store.types
    full = np.zeros((6, 6))
    full[2, 2] = full[3, 3] = full[4, 4] = _UNESTIMATED_VARIANCE
    full[np.ix_(_PLANAR, _PLANAR)] = covariance
    position = t["geometry_msgs/msg/Point"](x=float(pose[0]), y=float(pose[1]), z=0.0)
    vector = t["geometry_msgs/msg/Vector3"]
    return t["nav_msgs/msg/Odometry"](
        header=t["std_msgs/msg/Header"](stamp=stamp, frame_id=frame),
        child_frame_id=child_frame,
        pose=t["geometry_msgs/msg/PoseWithCovariance"](
            pose=t["geometry_msgs/msg/Pose"](
                position=position, orientation=_quaternion(store, float(pose[2]))
            ),
            covariance=full.ravel(),
        ),
        twist=t["geometry_msgs/msg/TwistWithCovariance"](
            twist=t["geometry_msgs/msg/Twist"](
                linear=vector(x=float(twist[0]), y=float(twist[1]), z=0.0),
                angular=vector(x=0.0, y=0.0, z=float(twist[2])),
            ),
            covariance=np.zeros(36),
        ),
    )


def _transform(store, stamp, frame, child_frame, pose):
    t = store.types
    translation = t["geometry_msgs/msg/Vector3"](x=float(pose[0]), y=float(pose[1]), z=0.0)
    stamped = t["geometry_msgs/msg/TransformStamped"](
        header=t["std_msgs/msg/Header"](stamp=stamp, frame_id=frame),
        child_frame_id=child_frame,
        transform=t["geometry_msgs/msg/Transform"](
            translation=translation, rotation=_quaternion(store, float(pose[2]))
        ),
    )
    return t["tf2_msgs/msg/TFMessage"](transforms=[stamped])
