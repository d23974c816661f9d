"""Writing odometry and sensor streams to MCAP files and ROS 2 bags with ``rosbags`` (see
the package). Every writer goes through ``_bag``: the file or folder appears whole or not at
all, and an existing folder is not replaced."""

from __future__ import annotations

import math
import os
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

from diffdrive._optional import optional
from diffdrive.io.ros.covariance import floored, planar_6x6
from diffdrive.io.tables import TableError

__all__ = ["BAG_FORMATS", "Stream", "write_odometry", "write_streams"]

BagFormat = Literal["mcap", "ros2"]
BAG_FORMATS: tuple[BagFormat, ...] = ("mcap", "ros2")
"""The bag formats written: one MCAP file, or a ROS 2 bag folder."""


def write_odometry(
    path: str | Path,
    times: object,
    poses: object,
    covariances: object = None,
    twists: object = None,
    twist_covariances: object = None,
    *,
    format: BagFormat | None = None,
    topic: str = "/odom",
    frame: str = "odom",
    child_frame: str = "base_link",
    tf: bool = True,
) -> Path:
    """Write poses ``(N, 3)`` at ``times`` ``(N,)`` (s, >= 0) as ``nav_msgs/Odometry`` on
    ``topic``, and ``frame -> child_frame`` on ``/tf`` when ``tf``.

    ``covariances`` ``(N, 3, 3)`` over ``(x, y, theta)`` fill the pose covariance and
    ``twist_covariances`` ``(N, 3, 3)`` over ``(vx, vy, omega)`` the twist's (z, roll and
    pitch, and their rates, get 1e6: not estimated); ``twists`` ``(N, 3)`` ``[vx, vy, omega]``
    the twist, in the child frame as ROS has it. A covariance or twist not given is zero: an
    exact trajectory (a simulation's, a ground truth), at rest unless ``twists`` says
    otherwise. Every covariance is written ``covariance.floored`` (no eigenvalue below 1e-9),
    so that a fuser can invert it. ``format`` is ``"mcap"`` (one MCAP file, what Foxglove
    opens) or ``"ros2"`` (a ROS 2 bag folder, for ``ros2 bag play``); default: ``mcap`` for a
    name ending in ``.mcap``, else ``ros2``. The file or folder appears whole or not at all; an
    existing folder is not replaced.
    """
    times, poses, covariances, twists, twist_covariances = _checked(
        times, poses, covariances, twists, twist_covariances
    )
    with _bag(path, format) as (writer, store):
        odometry = writer.add_connection(topic, "nav_msgs/msg/Odometry", typestore=store)
        transforms = writer.add_connection("/tf", "tf2_msgs/msg/TFMessage", typestore=store)
        for k in range(len(times)):
            stamp = _stamp(store, times[k])
            message = _odometry(
                store,
                stamp,
                (frame, child_frame),
                poses[k],
                covariances[k],
                twists[k],
                twist_covariances[k],
            )
            _write(writer, store, odometry, stamp, message)
            if tf:
                message = _transform(store, stamp, frame, child_frame, poses[k])
                _write(writer, store, transforms, stamp, message)
    return Path(path)


@contextmanager
def _bag(path: str | Path, format: BagFormat | None) -> Iterator[tuple]:
    """A ``rosbags`` writer and type store for a bag at ``path``, written whole or not at all
    (``format``: ``"mcap"``, one file; ``"ros2"``, a bag folder; None: by the suffix)."""
    rosbag2 = optional("rosbags.rosbag2", "ros", "writing ROS bags and MCAP")
    typesys = optional("rosbags.typesys", "ros", "writing ROS bags and MCAP")
    StoragePlugin, Writer = rosbag2.StoragePlugin, rosbag2.Writer
    Stores, get_typestore = typesys.Stores, typesys.get_typestore

    path = Path(path)
    format = format or ("mcap" if path.suffix == ".mcap" else "ros2")
    if format not in BAG_FORMATS:
        raise ValueError(f"format must be one of {', '.join(BAG_FORMATS)}, got {format!r}")
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
            yield writer, store
        if format == "mcap":
            os.replace(next(bag.glob("*.mcap")), path)
        else:
            os.rename(bag, path)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)


def _write(writer, store, connection, stamp, message) -> None:
    """One message, recorded at its stamp."""
    nanoseconds = stamp.sec * 1_000_000_000 + stamp.nanosec
    writer.write(connection, nanoseconds, store.serialize_cdr(message, message.__msgtype__))


@dataclass(frozen=True, eq=False)
class Stream:
    """One topic of ``write_streams``: ``kind`` is ``"joints"`` (``values`` ``(M, 2)`` wheel
    angles, rad, as ``sensor_msgs/JointState`` of the joints ``names``), ``"imu"`` (``(M, 3)``
    angular velocity, rad/s, ``sensor_msgs/Imu``), ``"fix"`` (``(M, 3)`` latitude, longitude
    (deg), height (m), ``sensor_msgs/NavSatFix``, with ``covariance`` ``(3, 3)`` m^2 over
    east, north, up if known), ``"pose"`` (``(M, 3)`` x, y, theta,
    ``geometry_msgs/PoseWithCovarianceStamped`` with ``covariance`` ``(3, 3)``),
    ``"odometry"`` (``(M, 6)`` x, y, theta, vx, vy, omega, ``nav_msgs/Odometry`` from
    ``frame`` to ``child_frame``, exact: a ground truth) or ``"twist"`` (``(M, 3)`` vx, vy,
    omega, ``geometry_msgs/Twist``); ``times`` ``(M,)`` s, the stamps (a ``Twist`` has none:
    its record time); ``recorded`` ``(M,)`` s, when each was recorded (default: its stamp;
    later for a measurement that arrives late)."""

    kind: Literal["joints", "imu", "fix", "pose", "odometry", "twist"]
    topic: str
    times: np.ndarray
    values: np.ndarray
    frame: str = "base_link"
    names: tuple[str, str] = ("left_wheel_joint", "right_wheel_joint")
    covariance: np.ndarray | None = None
    recorded: np.ndarray | None = None
    child_frame: str = "base_link"


def write_streams(path: str | Path, streams: list[Stream], format: BagFormat | None = None):
    """Write ``streams`` to one MCAP file or ROS 2 bag (see ``Stream`` and ``write_odometry``'s
    ``format``); ``diffdrive.io.ros``'s readers read every one back."""
    for stream in streams:
        times, values = np.asarray(stream.times, float), np.asarray(stream.values, float)
        width = {"joints": 2, "odometry": 6}.get(stream.kind, 3)
        if times.ndim != 1 or values.shape != (len(times), width):
            raise ValueError(
                f"{stream.topic}: times (M,) and values (M, {width}) must match, got "
                f"{times.shape} and {values.shape}"
            )
        _check_ros_times(times, f"{stream.topic}: times")
        if stream.recorded is not None:
            _check_ros_times(np.asarray(stream.recorded, float), f"{stream.topic}: record times")
        if stream.kind != "twist" and len(times) and times[0] == 0.0:
            raise ValueError(
                f"{stream.topic}: a stamp of 0 s reads as unset in ROS; start the times after "
                "0 (sensors.write_bag's time_offset)"
            )
    with _bag(path, format) as (writer, store):
        for stream in streams:
            msgtype, build = _MESSAGES[stream.kind]
            connection = writer.add_connection(stream.topic, msgtype, typestore=store)
            times = np.asarray(stream.times, float)
            recorded = times if stream.recorded is None else np.asarray(stream.recorded, float)
            rows = zip(times, recorded, np.asarray(stream.values, float), strict=True)
            for t, at, value in rows:
                message = build(store, _stamp(store, float(t)), stream, value)
                _write(writer, store, connection, _stamp(store, float(at)), message)
    return Path(path)


def _header(store, stamp, frame):
    return store.types["std_msgs/msg/Header"](stamp=stamp, frame_id=frame)


def _joints(store, stamp, stream, value):
    return store.types["sensor_msgs/msg/JointState"](
        header=_header(store, stamp, ""),
        name=list(stream.names),
        position=np.asarray(value, dtype=float),
        velocity=np.array([]),
        effort=np.array([]),
    )


def _imu(store, stamp, stream, value):
    t = store.types
    unknown = np.zeros(9)
    unknown[0] = -1.0  # sensor_msgs/Imu: -1 says "no orientation estimate"
    return t["sensor_msgs/msg/Imu"](
        header=_header(store, stamp, stream.frame),
        orientation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        orientation_covariance=unknown,
        angular_velocity=t["geometry_msgs/msg/Vector3"](
            x=float(value[0]), y=float(value[1]), z=float(value[2])
        ),
        angular_velocity_covariance=np.zeros(9),
        linear_acceleration=t["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
        linear_acceleration_covariance=unknown,
    )


# sensor_msgs/NavSatFix's position_covariance_type: unknown, and a diagonal or full matrix known.
_COVARIANCE_UNKNOWN, _DIAGONAL_KNOWN, _COVARIANCE_KNOWN = 0, 2, 3


def _fix(store, stamp, stream, value):
    t = store.types
    if stream.covariance is None or not np.any(stream.covariance):
        # NavSatFix's own word for "no covariance", which its readers know (not a singular one)
        covariance, kind = np.zeros(9), _COVARIANCE_UNKNOWN
    else:
        matrix = floored(stream.covariance)
        diagonal = not np.any(matrix - np.diag(np.diag(matrix)))
        covariance, kind = matrix.ravel(), _DIAGONAL_KNOWN if diagonal else _COVARIANCE_KNOWN
    return t["sensor_msgs/msg/NavSatFix"](
        header=_header(store, stamp, stream.frame),
        status=t["sensor_msgs/msg/NavSatStatus"](status=0, service=1),
        latitude=float(value[0]),
        longitude=float(value[1]),
        altitude=float(value[2]),
        position_covariance=covariance,
        position_covariance_type=kind,
    )


def _pose(store, stamp, stream, value):
    t = store.types
    planar = np.zeros((3, 3)) if stream.covariance is None else stream.covariance
    position = t["geometry_msgs/msg/Point"](x=float(value[0]), y=float(value[1]), z=0.0)
    return t["geometry_msgs/msg/PoseWithCovarianceStamped"](
        header=_header(store, stamp, stream.frame),
        pose=t["geometry_msgs/msg/PoseWithCovariance"](
            pose=t["geometry_msgs/msg/Pose"](
                position=position, orientation=_quaternion(store, float(value[2]))
            ),
            covariance=planar_6x6(planar),
        ),
    )


def _twist(store, stamp, stream, value):
    vector = store.types["geometry_msgs/msg/Vector3"]
    return store.types["geometry_msgs/msg/Twist"](
        linear=vector(x=float(value[0]), y=float(value[1]), z=0.0),
        angular=vector(x=0.0, y=0.0, z=float(value[2])),
    )


def _ground_truth(store, stamp, stream, value):
    exact = np.zeros((3, 3))
    frames = (stream.frame, stream.child_frame)
    return _odometry(store, stamp, frames, value[:3], exact, value[3:], exact)


_MESSAGES = {
    "joints": ("sensor_msgs/msg/JointState", _joints),
    "odometry": ("nav_msgs/msg/Odometry", _ground_truth),
    "imu": ("sensor_msgs/msg/Imu", _imu),
    "fix": ("sensor_msgs/msg/NavSatFix", _fix),
    "pose": ("geometry_msgs/msg/PoseWithCovarianceStamped", _pose),
    "twist": ("geometry_msgs/msg/Twist", _twist),
}


def _checked(times: object, poses: object, *optional: object) -> tuple[np.ndarray, ...]:
    """``times`` ``(N,)``, ``poses`` ``(N, 3)`` and the optional covariances ``(N, 3, 3)``,
    twists ``(N, 3)`` and twist covariances ``(N, 3, 3)`` (zeros where None), checked."""
    times = np.asarray(times, dtype=float)
    poses = np.asarray(poses, dtype=float)
    if times.ndim != 1 or poses.shape != (len(times), 3) or len(times) == 0:
        raise ValueError(
            f"times (N,) and poses (N, 3) must match, got {times.shape}, {poses.shape}"
        )
    arrays = [times, poses]
    names = ("covariances", "twists", "twist_covariances")
    for name, given, shape in zip(names, optional, ((3, 3), (3,), (3, 3)), strict=True):
        wanted = (len(times), *shape)
        array = np.zeros(wanted) if given is None else np.asarray(given, dtype=float)
        if array.shape != wanted:
            raise ValueError(f"{name} must be {wanted}, got {array.shape}")
        arrays.append(array)
    for name, array in zip(("times", "poses", *names), arrays, strict=True):
        if not np.all(np.isfinite(array)):
            raise ValueError(f"{name} must be finite")
    _check_ros_times(times, "times")
    return tuple(arrays)


def _check_ros_times(times: np.ndarray, what: str) -> None:
    """Refuse stamps a ROS 2 ``Time`` (int32 seconds) cannot hold, or that do not increase."""
    if not len(times):
        return
    if not np.all(np.isfinite(times)):
        raise ValueError(f"{what} must be finite")
    if times.min() < 0 or times.max() >= 2.0**31:
        raise ValueError(
            f"{what} must lie in [0, 2^31) s, what a ROS 2 stamp's signed 32-bit seconds hold; "
            f"got {times.min():.3f} to {times.max():.3f} s"
        )
    if np.any(np.diff(times) <= 0):
        raise ValueError(f"{what} must increase")


def _stamp(store, seconds: float):
    Time = store.types["builtin_interfaces/msg/Time"]
    whole = math.floor(seconds)
    # The fraction apart: seconds * 1e9 would round to 256 ns at stamps since 1970.
    nanoseconds = whole * 1_000_000_000 + round((seconds - whole) * 1e9)
    return Time(sec=nanoseconds // 1_000_000_000, nanosec=nanoseconds % 1_000_000_000)


def _quaternion(store, yaw: float):
    Quaternion = store.types["geometry_msgs/msg/Quaternion"]
    return Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))


def _odometry(store, stamp, frames, pose, covariance, twist, twist_covariance):
    t = store.types
    frame, child_frame = frames
    position = t["geometry_msgs/msg/Point"](x=float(pose[0]), y=float(pose[1]), z=0.0)
    vector = t["geometry_msgs/msg/Vector3"]
    return t["nav_msgs/msg/Odometry"](
        header=t["std_msgs/msg/Header"](stamp=stamp, frame_id=frame),
        child_frame_id=child_frame,
        pose=t["geometry_msgs/msg/PoseWithCovariance"](
            pose=t["geometry_msgs/msg/Pose"](
                position=position, orientation=_quaternion(store, float(pose[2]))
            ),
            covariance=planar_6x6(covariance),
        ),
        twist=t["geometry_msgs/msg/TwistWithCovariance"](
            twist=t["geometry_msgs/msg/Twist"](
                linear=vector(x=float(twist[0]), y=float(twist[1]), z=0.0),
                angular=vector(x=0.0, y=0.0, z=float(twist[2])),
            ),
            covariance=planar_6x6(twist_covariance),
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
