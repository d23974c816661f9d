"""Dynamics: how the drive answers a command.

- ``lag``: ``first_order`` and ``decay``, the first-order lag every drive model steps through
  (``DriveModel``, ``control.follow``, the ``Predictive`` tracker).

- ``response``: ``identify_velocity_response``, a velocity-commanded drive's pure delay,
  first-order time constant, gain and acceleration limit, fitted to a log of commands and
  measured wheel velocities; ``VelocityResponse.predict`` drives the model with commands;
  ``cross_validate_response`` scores it on held-out time against the instant kinematic response.

- ``voltage``: ``identify_voltage_response``, a voltage-driven wheel's kS, kV and kA (SysId's
  regression) with the measurement's delay found from the data; ``identify_drivetrain``, the
  same on a drivetrain's linear and angular channels (WPILib's four-constant form);
  ``Feedforward``.

- ``drive``: ``DriveModel`` (either model, or what an identification found) and
  ``simulate_commands``: commands through the drive to wheel velocities to poses, batched.

- ``identify``: ``identify_drive``, a log's voltages or commands to the drive's kS, kV, kA
  (in WPILib's units) and velocity response in one call, as ``diffdrive identify`` writes.
"""

from diffdrive.dynamics.drive import DriveModel, simulate_commands
from diffdrive.dynamics.identify import DriveIdentification, identify_drive
from diffdrive.dynamics.response import (
    HeldOutResponse,
    VelocityResponse,
    cross_validate_response,
    identify_velocity_response,
)
from diffdrive.dynamics.voltage import (
    DrivetrainResponse,
    Feedforward,
    VoltageResponse,
    identify_drivetrain,
    identify_voltage_response,
)

__all__ = [
    "DriveIdentification",
    "DriveModel",
    "DrivetrainResponse",
    "Feedforward",
    "HeldOutResponse",
    "VelocityResponse",
    "VoltageResponse",
    "cross_validate_response",
    "identify_drive",
    "identify_drivetrain",
    "identify_velocity_response",
    "identify_voltage_response",
    "simulate_commands",
]
