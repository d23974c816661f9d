"""Robot logs: ROS 1 bags, ROS 2 bags and MCAP files in and out, without ROS installed.

Built on ``rosbags`` (``pip install 'diffdrive[ros]'``), imported only here. Readers return
arrays with time stamps in seconds and say which stamp they used: the message header's
(``"header"``) or, for messages without one or with an empty one, the time the bag recorded it
(``"record"``). Messages are sorted by that stamp; one whose stamp equals the one before is
dropped (counted in ``dropped``), since a log's times must increase.

- ``read_joint_states``: wheel positions or velocities, **looked up by joint name**;
- ``read_odometry``: ``nav_msgs/Odometry`` poses, twists and covariances;
- ``read_wheel_motion``: the wheels from a drive controller's ``Odometry`` or a ``Twist``
  topic, for a bag without joint states;
- ``read_imu``, ``read_twists`` (``Twist``/``TwistStamped`` commands), ``read_tf`` (a
  parent-to-child chain as a trajectory), ``read_navsatfix`` (to a local east-north frame);
- ``topics``: what a bag holds, and which topics diffdrive can use;
- ``FLOOR``, ``UNESTIMATED``, ``floored``: the covariances every written message carries,
  positive definite (``covariance``);
- ``write_odometry``: ``nav_msgs/Odometry`` with the propagated covariance and ``/tf``, to an
  MCAP file or a ROS 2 bag folder, written atomically.
"""

from diffdrive.io.ros.covariance import FLOOR, UNESTIMATED, floored
from diffdrive.io.ros.reader import (
    BagError,
    Imu,
    NavSatFix,
    OdometryTopic,
    Topic,
    Twists,
    joint_names,
    read_imu,
    read_joint_states,
    read_navsatfix,
    read_odometry,
    read_tf,
    read_twists,
    read_wheel_motion,
    topics,
)
from diffdrive.io.ros.writer import BAG_FORMATS, Stream, write_odometry, write_streams
from diffdrive.io.sniff import is_bag

__all__ = [
    "BAG_FORMATS",
    "FLOOR",
    "UNESTIMATED",
    "BagError",
    "Imu",
    "NavSatFix",
    "OdometryTopic",
    "Stream",
    "Topic",
    "Twists",
    "floored",
    "is_bag",
    "joint_names",
    "read_imu",
    "read_joint_states",
    "read_navsatfix",
    "read_odometry",
    "read_tf",
    "read_twists",
    "read_wheel_motion",
    "topics",
    "write_odometry",
    "write_streams",
]
