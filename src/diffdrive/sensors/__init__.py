"""Synthetic sensor streams with real error sources, seeded and batched over robots: what a
robot would log along a trajectory (a ``simulate`` result, a batch of them, or a reference read
from a file or bag), with the truth to test estimators against.

- ``encoders``: ``encoder_readings``: counts with quantisation and counter roll-over, radius
  and track biases, wheel random-walk noise (``Odometry``'s ``k``), labelled slips, sampling
  jitter, latency and dropped samples; a robot's readings as a ``Run``;
- ``gyro``: ``gyro_readings``: yaw rates with bias, bias instability, angle and rate random
  walk, scale error and a mounting rotation (an IMU's three rates);
- ``absolute``: ``absolute_readings``: poses or positions (GPS, in latitude and longitude)
  with noise, latency, dropouts and labelled outliers;
- ``commands``: ``commands_of``: the twists and wheel velocities a controller would have sent;
- ``output``: ``write_bag`` (a ROS 2 bag or MCAP file: ``JointState``, ``Imu``, ``NavSatFix``,
  ``PoseWithCovarianceStamped``, ``Twist``, and the truth as ``Odometry`` on
  ``/ground_truth``) and ``write_table`` (a wheel-log table).
"""

from diffdrive.sensors.absolute import AbsoluteModel, AbsoluteReadings, absolute_readings
from diffdrive.sensors.commands import Commands, commands_of
from diffdrive.sensors.encoders import EncoderModel, EncoderReadings, Slip, encoder_readings
from diffdrive.sensors.gyro import GyroModel, GyroReadings, gyro_readings
from diffdrive.sensors.output import bag_time_offset, streams_of, write_bag, write_table

__all__ = [
    "AbsoluteModel",
    "AbsoluteReadings",
    "Commands",
    "EncoderModel",
    "EncoderReadings",
    "GyroModel",
    "GyroReadings",
    "Slip",
    "absolute_readings",
    "bag_time_offset",
    "commands_of",
    "encoder_readings",
    "gyro_readings",
    "streams_of",
    "write_bag",
    "write_table",
]
