"""Dynamics: how the drive answers a command.

- ``response``: ``identify_velocity_response``, a velocity-commanded drive's pure delay,
  first-order time constant, gain and acceleration limit, fitted to a log of commands and
  measured wheel velocities; ``VelocityResponse.predict`` drives the model with commands.

Next: voltage-driven drives (kS, kV, kA), feedforward, and simulation through the model.
"""

from diffdrive.dynamics.response import VelocityResponse, identify_velocity_response

__all__ = ["VelocityResponse", "identify_velocity_response"]
