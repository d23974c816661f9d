"""Reading ROS 1 bags, ROS 2 bag folders and MCAP files with ``rosbags`` (see the package)."""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from diffdrive._validate import geodetic_point
from diffdrive.io.run import Run, WheelKind
from diffdrive.io.tables import TableError

__all__ = [
    "BagError",
    "Imu",
    "NavSatFix",
    "OdometryTopic",
    "Topic",
    "Twists",
    "joint_names",
    "read_imu",
    "read_joint_states",
    "read_navsatfix",
    "read_odometry",
    "read_tf",
    "read_twists",
    "read_wheel_motion",
    "topics",
]

# What diffdrive can do with a topic of each type, for ``topics`` and ``diffdrive info``.
USES = {
    "sensor_msgs/msg/JointState": "wheels: odometry/estimate/calibrate --joint-topic",
    "nav_msgs/msg/Odometry": "a trajectory: --topic; a reference: --truth-topic; poses: "
    "estimate/calibrate-driving --pose-topic; or the wheels: --wheel-topic",
    "sensor_msgs/msg/Imu": "a gyro: estimate/calibrate-gyro/calibrate-driving --gyro-topic",
    "geometry_msgs/msg/Twist": "commands (v, omega), or the wheels: --wheel-topic",
    "geometry_msgs/msg/TwistStamped": "commands (v, omega), or the wheels: --wheel-topic",
    "tf2_msgs/msg/TFMessage": "a trajectory of a frame: --topic tf:PARENT:CHILD",
    "sensor_msgs/msg/NavSatFix": "GPS fixes: estimate/calibrate-driving --gps-topic (local east, "
    "north from --datum, else the first fix); a reference: --truth-topic",
    "geometry_msgs/msg/PoseWithCovarianceStamped": "poses (a camera, a localiser): "
    "estimate/calibrate-driving --pose-topic, or --topic",
}


class BagError(TableError):
    """A bag that cannot give what was asked: the message names the bag, topic or joint."""


def _rosbags():
    try:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore
    except ModuleNotFoundError:
        raise ImportError("reading ROS bags needs rosbags: pip install 'diffdrive[ros]'") from None
    return AnyReader, Stores, get_typestore


@contextlib.contextmanager
def _open(path: str | Path) -> Iterator:
    """An open ``AnyReader`` over one bag (ROS 1 bag, ROS 2 bag folder or MCAP file)."""
    any_reader, stores, get_typestore = _rosbags()
    path = Path(path)
    if not path.exists():
        raise BagError(f"{path}: no such bag")
    try:
        reader = any_reader([path], default_typestore=get_typestore(stores.ROS1_NOETIC))
        reader.open()
    except Exception as exc:  # rosbags raises its own errors for empty or broken files
        raise BagError(f"{path}: not a readable bag: {exc}") from None
    try:
        yield reader
    finally:
        reader.close()


@dataclass(frozen=True, eq=False)
class Topic:
    """One topic of a bag: its message type, count, mean rate (Hz) and what diffdrive can
    do with it (empty when nothing)."""

    name: str
    msgtype: str
    count: int
    rate: float
    use: str


def topics(path: str | Path) -> list[Topic]:
    """The topics of a bag, in name order."""
    with _open(path) as reader:
        found: dict[tuple[str, str], int] = {}
        for connection in reader.connections:
            name, kind = connection.topic, connection.msgtype
            count = found.get((name, kind), 0) + connection.msgcount
            found[(name, kind)] = count
        duration = max(reader.duration * 1e-9, 1e-9)
    return [
        Topic(name, kind, count, (count - 1) / duration if count > 1 else 0.0, USES.get(kind, ""))
        for (name, kind), count in sorted(found.items())
    ]


def joint_names(path: str | Path, topic: str = "/joint_states") -> list[str]:
    """The joint names of a ``sensor_msgs/JointState`` topic's first message, in its order."""
    path = Path(path)
    with _open(path) as reader:
        for _, message in _messages(reader, path, topic, ("sensor_msgs/msg/JointState",)):
            return list(message.name)
    raise BagError(f"{path}: {topic} has no messages")


def _messages(reader, path: Path, topic: str, kinds: tuple[str, ...]):
    """``(record time ns, message)`` of ``topic``, which must have one of the ``kinds``."""
    connections = [c for c in reader.connections if c.topic == topic]
    if not connections:
        listed = ", ".join(sorted({c.topic for c in reader.connections})) or "none"
        raise BagError(f"{path}: no topic {topic!r} (the bag has: {listed})")
    wrong = [c.msgtype for c in connections if c.msgtype not in kinds]
    if wrong:
        raise BagError(f"{path}: {topic} holds {wrong[0]}, not {' or '.join(kinds)}")
    try:
        for connection, stamp, raw in reader.messages(connections=connections):
            yield stamp, reader.deserialize(raw, connection.msgtype)
    except Exception as exc:  # a truncated bag fails inside rosbags
        raise BagError(f"{path}: {topic}: cannot read every message: {exc}") from None


def _stamp(message) -> float | None:
    """The header stamp in s, or None when there is no header or its stamp is zero."""
    header = getattr(message, "header", None)
    if header is not None and (header.stamp.sec or header.stamp.nanosec):
        return header.stamp.sec + header.stamp.nanosec * 1e-9
    return None


@dataclass(frozen=True)
class _Stamped:
    times: np.ndarray
    order: np.ndarray
    source: str
    dropped: int


def _order(headers: list[float | None], recorded: list[float], path: Path, topic: str) -> _Stamped:
    """Sort by stamp; drop a message whose stamp equals the one before (stated rule).

    The stamps are the header stamps when every message has one, else the record times of
    all: a header clock and the recorder's cannot be ordered together (two messages without
    a header stamp sorted 1.7e9 s after the rest, and the robot drove back).
    """
    if not recorded:
        raise BagError(f"{path}: {topic} has no messages")
    missing = sum(stamp is None for stamp in headers)
    if missing == 0:
        times, source = np.array(headers, dtype=float), "header"
    elif missing == len(headers):
        times, source = np.array(recorded), "record"
    else:
        times = np.array(recorded)
        source = f"record (as {missing} of {len(headers)} messages have no header stamp)"
    order = np.argsort(times, kind="stable")
    keep = np.concatenate([[True], np.diff(times[order]) > 0])
    return _Stamped(times[order][keep], order[keep], source, int(np.count_nonzero(~keep)))


def _yaw(q) -> float:
    """The yaw of a quaternion message (rotation about z), rad."""
    return math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))


def _collect(path: Path, topic: str, kinds: tuple[str, ...], extract) -> tuple:
    """``(stamps, rows, last message)`` of a topic, in stamp order (see ``_order``):
    ``extract(message)`` gives a message's row, or None to skip it."""
    headers: list[float | None] = []
    records: list[float] = []
    rows, last = [], None
    with _open(path) as reader:
        for recorded, message in _messages(reader, path, topic, kinds):
            row = extract(message)
            if row is None:
                continue
            rows.append(row)
            headers.append(_stamp(message))
            records.append(recorded * 1e-9)
            last = message
    ordered = _order(headers, records, path, topic)
    return ordered, np.array(rows, dtype=float)[ordered.order], last


def read_joint_states(
    path: str | Path,
    left_joint: str,
    right_joint: str,
    topic: str = "/joint_states",
    field: str | None = None,
) -> Run:
    """The wheels of ``sensor_msgs/JointState`` messages as a ``Run``.

    Joints are looked up by name in every message. ``field`` is ``"position"`` (accumulated
    angles, rad) or ``"velocity"`` (rad/s, held until the next message, as every log); the
    default is position when the messages have it.
    """
    path = Path(path)
    if field not in (None, "position", "velocity"):
        raise ValueError(f"field must be 'position', 'velocity' or None, got {field!r}")
    if left_joint == right_joint:
        raise ValueError(f"the left and right wheels are one joint, {left_joint!r}: name both")
    chosen = [field]

    def wheels(message):
        names = list(message.name)
        missing = [j for j in (left_joint, right_joint) if j not in names]
        if missing:
            raise BagError(
                f"{path}: {topic} has no joint {missing[0]!r} (its joints: "
                f"{', '.join(names) or 'none'})"
            )
        if chosen[0] is None:
            chosen[0] = "position" if len(message.position) == len(names) else "velocity"
        values = getattr(message, chosen[0])
        if len(values) != len(names):
            raise BagError(f"{path}: {topic}: a message has no {chosen[0]} for each joint")
        return values[names.index(left_joint)], values[names.index(right_joint)]

    ordered, rows, _ = _collect(path, topic, ("sensor_msgs/msg/JointState",), wheels)
    if len(rows) < 2 or not np.all(np.isfinite(rows)):
        raise BagError(f"{path}: {topic}: needs 2 or more messages of finite wheel {chosen[0]}s")
    kind: WheelKind = "angle" if chosen[0] == "position" else "velocity"
    return Run(ordered.times, kind, rows, None, f"{path} {topic} ({ordered.source} stamps)")


@dataclass(frozen=True, eq=False)
class OdometryTopic:
    """``nav_msgs/Odometry`` (or ``geometry_msgs/PoseWithCovarianceStamped``, whose twists
    are zero and child frame empty): ``times`` ``(N,)`` s, ``poses`` ``(N, 3)`` ``[x, y, yaw]``
    (yaw unwrapped), ``twists`` ``(N, 3)`` ``[vx, vy, omega]``, ``covariances`` ``(N, 3, 3)``
    over ``(x, y, yaw)``, ``twist_covariances`` ``(N, 3, 3)`` over ``(vx, vy, omega)``, the
    frames, which stamp was used and how many were dropped."""

    times: np.ndarray
    poses: np.ndarray
    twists: np.ndarray
    covariances: np.ndarray
    twist_covariances: np.ndarray
    frame: str
    child_frame: str
    stamp_source: str
    dropped: int


def read_odometry(path: str | Path, topic: str) -> OdometryTopic:
    """The poses, twists and covariances of a ``nav_msgs/Odometry`` topic (or a
    ``geometry_msgs/PoseWithCovarianceStamped`` one: a camera's or a localiser's poses)."""

    def row(m):
        p = m.pose.pose
        t = m.twist.twist if hasattr(m, "twist") else _NO_TWIST
        spread = m.twist.covariance if hasattr(m, "twist") else np.zeros(36)
        return (
            p.position.x,
            p.position.y,
            _yaw(p.orientation),
            t.linear.x,
            t.linear.y,
            t.angular.z,
            *_planar(m.pose.covariance),
            *_planar(spread),
        )

    kinds = ("nav_msgs/msg/Odometry", "geometry_msgs/msg/PoseWithCovarianceStamped")
    ordered, rows, last = _collect(Path(path), topic, kinds, row)
    poses = rows[:, :3].copy()
    poses[:, 2] = np.unwrap(poses[:, 2])
    return OdometryTopic(
        ordered.times,
        poses,
        rows[:, 3:6],
        rows[:, 6:15].reshape(-1, 3, 3),
        rows[:, 15:].reshape(-1, 3, 3),
        last.header.frame_id,
        getattr(last, "child_frame_id", ""),
        ordered.source,
        ordered.dropped,
    )


def _planar(covariance) -> np.ndarray:
    """The ``(x, y, yaw)`` block (or their rates') of ROS's row-major 6x6, as 9 values."""
    full = np.asarray(covariance, dtype=float).reshape(6, 6)
    return full[np.ix_([0, 1, 5], [0, 1, 5])].ravel()


class _Still:
    """A twist of zeros, for a pose message that has none."""

    class _Zero:
        x = y = z = 0.0

    linear = angular = _Zero()


_NO_TWIST = _Still()


@dataclass(frozen=True, eq=False)
class Imu:
    """``sensor_msgs/Imu`` in its own frame: ``angular_velocity`` ``(N, 3)`` rad/s,
    ``orientation`` ``(N, 4)`` ``[x, y, z, w]``, ``linear_acceleration`` ``(N, 3)`` m/s^2."""

    times: np.ndarray
    angular_velocity: np.ndarray
    orientation: np.ndarray
    linear_acceleration: np.ndarray
    frame: str
    stamp_source: str
    dropped: int


def read_imu(path: str | Path, topic: str) -> Imu:
    """An IMU topic as arrays, in the IMU's frame (rotate to the body yourself)."""

    def row(m):
        w, q, a = m.angular_velocity, m.orientation, m.linear_acceleration
        return (w.x, w.y, w.z, q.x, q.y, q.z, q.w, a.x, a.y, a.z)

    ordered, rows, last = _collect(Path(path), topic, ("sensor_msgs/msg/Imu",), row)
    return Imu(
        ordered.times,
        rows[:, :3],
        rows[:, 3:7],
        rows[:, 7:],
        last.header.frame_id,
        ordered.source,
        ordered.dropped,
    )


@dataclass(frozen=True, eq=False)
class Twists:
    """Commands: ``times`` ``(N,)`` s and ``twists`` ``(N, 2)`` ``[v, omega]`` (m/s, rad/s)."""

    times: np.ndarray
    twists: np.ndarray
    stamp_source: str
    dropped: int


def read_twists(path: str | Path, topic: str = "/cmd_vel") -> Twists:
    """``geometry_msgs/Twist`` or ``TwistStamped`` commands (``Twist`` has record times)."""

    def row(m):
        twist = getattr(m, "twist", m)
        return (twist.linear.x, twist.angular.z)

    kinds = ("geometry_msgs/msg/Twist", "geometry_msgs/msg/TwistStamped")
    ordered, rows, _ = _collect(Path(path), topic, kinds, row)
    return Twists(ordered.times, rows, ordered.source, ordered.dropped)


# What a wheel topic may be: a drive controller's own odometry, or the twists it drove.
WHEEL_TOPIC_TYPES = (
    "nav_msgs/msg/Odometry",
    "geometry_msgs/msg/TwistStamped",
    "geometry_msgs/msg/Twist",
)


def read_wheel_motion(path: str | Path, topic: str, robot) -> Run:
    """The wheels of ``robot`` (any model) as a bag without joint states has them: from a
    ``nav_msgs/Odometry`` topic (a drive controller's own odometry, the Husky's), the motion
    between consecutive poses (the SE(2) logarithm of the relative pose: the forward travel
    and turn the controller integrated) through the robot's inverse kinematics, as
    accumulated wheel angles; from a ``Twist`` or ``TwistStamped`` topic, each twist's wheel
    velocities, held until the next message. A sideways part is not used (a wheeled robot's
    body does not slide); the ``Run``'s ``source`` says what was read."""
    from diffdrive import batch

    path = Path(path)
    with _open(path) as reader:
        kinds = {c.msgtype for c in reader.connections if c.topic == topic}
    if kinds and not kinds & set(WHEEL_TOPIC_TYPES):
        raise BagError(
            f"{path}: {topic} holds {sorted(kinds)[0]}; a wheel topic is one of "
            f"{', '.join(WHEEL_TOPIC_TYPES)}"
        )
    if "nav_msgs/msg/Odometry" in kinds:
        odometry = read_odometry(path, topic)
        if len(odometry.times) < 2:
            raise BagError(f"{path}: {topic} needs 2 or more messages")
        motion = batch.log(batch.relative_to(odometry.poses[1:], odometry.poses[:-1]))
        motion[:, 1] = 0.0
        increments = batch.to_wheel_velocities(robot, motion)
        angles = np.concatenate([np.zeros((1, 2)), np.cumsum(increments, axis=0)])
        where = f"{path} {topic} (the controller's poses, {odometry.stamp_source} stamps)"
        reported = odometry.twists[:, [0, 2]]  # what the controller says it drove
        return Run(odometry.times, "angle", angles, None, where, reported=reported)
    twists = read_twists(path, topic)  # names a topic of another type, or a missing one
    if len(twists.times) < 2:
        raise BagError(f"{path}: {topic} needs 2 or more messages")
    v, omega = twists.twists.T
    wheels = batch.to_wheel_velocities(robot, np.column_stack([v, 0.0 * v, omega]))
    where = f"{path} {topic} (twists held until the next, {twists.stamp_source} stamps)"
    return Run(twists.times, "velocity", wheels, None, where)


def read_tf(path: str | Path, parent: str, child: str) -> tuple[np.ndarray, np.ndarray]:
    """The pose ``(N, 3)`` of frame ``child`` in frame ``parent`` at times ``(N,)`` s, from
    ``/tf`` and ``/tf_static``.

    The chain from ``parent`` to ``child`` may pass through other frames; the poses are taken
    at the stamps of the chain's last link, each other link holding its latest transform
    (static ones always). Planar: each link's x, y and yaw.
    """
    path = Path(path)
    links: dict[str, tuple[str, list]] = {}  # child frame -> (its parent, [(t, x, y, yaw)])
    with _open(path) as reader:
        tf_topics = [
            t for t in ("/tf", "/tf_static") if any(c.topic == t for c in reader.connections)
        ]
        if not tf_topics:
            raise BagError(f"{path}: no /tf or /tf_static topic")
        for topic in tf_topics:
            for _, m in _messages(reader, path, topic, ("tf2_msgs/msg/TFMessage",)):
                for transform in m.transforms:
                    name = transform.child_frame_id.lstrip("/")
                    above = transform.header.frame_id.lstrip("/")
                    stamp = transform.header.stamp.sec + transform.header.stamp.nanosec * 1e-9
                    if topic == "/tf_static":
                        stamp = -math.inf
                    t, r = transform.transform.translation, transform.transform.rotation
                    links.setdefault(name, (above, []))[1].append((stamp, t.x, t.y, _yaw(r)))
    chain = _chain(links, parent.lstrip("/"), child.lstrip("/"), path)
    return _compose_chain(links, chain, path)


def _chain(links: dict, parent: str, child: str, path: Path) -> list[str]:
    """The frames from ``child`` up to (not including) ``parent``."""
    chain, frame = [], child
    while frame != parent:
        if frame not in links or frame in chain:
            known = ", ".join(f"{above}->{name}" for name, (above, _) in sorted(links.items()))
            raise BagError(f"{path}: no transform chain {parent} -> {child} (it has: {known})")
        chain.append(frame)
        frame = links[frame][0]
    return chain


def _compose_chain(links: dict, chain: list[str], path: Path):
    """The chain's poses at the stamps of its moving link nearest the child; every link
    holds its latest transform at those times (a static one always)."""
    from diffdrive import batch

    samples = {}
    for frame in chain:
        table = np.array(sorted(links[frame][1]))
        samples[frame] = table[np.concatenate([[True], np.diff(table[:, 0]) > 0])]
    moving = [frame for frame in chain if np.isfinite(samples[frame][:, 0]).any()]
    if not moving:
        raise BagError(f"{path}: the chain is static: no times to make a trajectory of")
    times = samples[moving[0]][:, 0]
    times = times[np.isfinite(times)]
    poses = np.zeros((len(times), 3))
    for frame in chain:  # from the child up: parent_pose = link * child_pose
        table = samples[frame]
        index = np.searchsorted(table[:, 0], times, side="right") - 1
        if np.any(index < 0):
            first = times[np.argmax(index < 0)]
            raise BagError(f"{path}: no transform to {frame} yet at t = {first:.9f} s")
        poses = batch.compose(table[index, 1:], poses)
    poses[:, 2] = np.unwrap(poses[:, 2])
    return times, poses


@dataclass(frozen=True, eq=False)
class NavSatFix:
    """GPS fixes: ``times`` ``(N,)`` s, ``latitude``, ``longitude`` (deg), ``altitude`` (m),
    and ``east``, ``north`` (m) in the local tangent plane (WGS84, by pymap3d) at ``datum``
    ``(lat deg, lon deg, altitude m)``, the first fix unless given; ``variance`` ``(N,)`` m^2,
    the mean of the east and north variances. The frame is REP-103's ENU: x east, y north,
    a heading counter-clockwise from east (as robot_localization's ``navsat_transform``)."""

    times: np.ndarray
    latitude: np.ndarray
    longitude: np.ndarray
    altitude: np.ndarray
    east: np.ndarray
    north: np.ndarray
    variance: np.ndarray
    stamp_source: str
    dropped: int
    datum: tuple[float, float, float]

    @property
    def positions(self) -> np.ndarray:
        """``(N, 2)`` ``[east, north]``, m."""
        return np.column_stack([self.east, self.north])


def read_navsatfix(path: str | Path, topic: str, datum: object = None) -> NavSatFix:
    """The fixes of a ``sensor_msgs/NavSatFix`` topic with a fix (status >= 0), in the local
    east-north frame at ``datum`` ``(lat deg, lon deg, altitude m)``; without one, at the first
    fix (a noisy point: the frame is then off any other by that fix's error)."""
    try:
        import pymap3d
    except ModuleNotFoundError:
        raise ImportError("GPS fixes need pymap3d: pip install 'diffdrive[ros]'") from None
    origin = None if datum is None else geodetic_point("datum", datum)

    def row(m):
        position = (m.latitude, m.longitude, m.altitude)
        if m.status.status < 0 or not all(math.isfinite(v) for v in position):
            return None  # no fix
        covariance = m.position_covariance
        return (*position, 0.5 * (covariance[0] + covariance[4]))

    ordered, rows, _ = _collect(Path(path), topic, ("sensor_msgs/msg/NavSatFix",), row)
    latitude, longitude, altitude, variance = rows.T
    if origin is None:
        origin = (float(latitude[0]), float(longitude[0]), float(altitude[0]))
    east, north, _ = pymap3d.geodetic2enu(latitude, longitude, altitude, *origin)
    return NavSatFix(
        ordered.times,
        latitude,
        longitude,
        altitude,
        np.asarray(east),
        np.asarray(north),
        variance,
        ordered.source,
        ordered.dropped,
        origin,
    )
