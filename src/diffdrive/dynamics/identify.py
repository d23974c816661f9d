"""A drive identified from a robot's log in one call: its kS, kV, kA (from voltages), its
velocity response (from commands), or both, as a drive file holds them
(``diffdrive.io.drives``) and ``diffdrive identify`` writes.

- With the wheels' ``voltages``: ``identify_drivetrain`` on the wheels' surface speeds (the
  wheel velocities times their radii, m/s), so kS, kV, kA come in WPILib's and SysId's units
  (V, V s/m, V s^2/m), the linear channel (the wheels' mean) and the angular one (half their
  difference).
- With ``commands`` (wheel velocities, rad/s, each held from its stamp): the velocity
  response, ``identify_velocity_response`` (delay, lag, gain, acceleration limit).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from diffdrive.dynamics.response import VelocityResponse, identify_velocity_response
from diffdrive.dynamics.voltage import DrivetrainResponse, identify_drivetrain
from diffdrive.model import Robot

__all__ = ["DriveIdentification", "identify_drive"]


@dataclass(frozen=True, eq=False)
class DriveIdentification:
    """``identify_drive``'s result: the ``drivetrain`` (kS, kV, kA per channel, velocities in
    m/s) and the velocity ``response``, each None when the log could not show it."""

    drivetrain: DrivetrainResponse | None
    response: VelocityResponse | None

    def sections(self) -> dict[str, dict[str, float]]:
        """As a drive file's sections (``diffdrive.io.write_drive``)."""
        sections: dict[str, dict[str, float]] = {}
        if self.drivetrain is not None:
            for name, channel in (
                ("feedforward", self.drivetrain.linear),
                ("angular", self.drivetrain.angular),
            ):
                gains = channel.feedforward
                sections[name] = {
                    "ks": gains.ks,
                    "kv": gains.kv,
                    "ka": gains.ka,
                    "delay": channel.delay,
                }
        if self.response is not None:
            found = self.response
            sections["response"] = {
                "delay": found.delay,
                "time_constant": found.time_constant,
                "gain": found.gain,
            }
            if math.isfinite(found.acceleration):
                sections["response"]["acceleration"] = found.acceleration
        return sections


def identify_drive(
    robot: Robot,
    times: object,
    velocities: object,
    *,
    voltages: object = None,
    command_times: object = None,
    commands: object = None,
    accelerations: tuple[float, ...] = (math.inf,),
) -> DriveIdentification:
    """The drive of ``robot`` from its wheels' measured ``velocities`` ``(N, 2)`` rad/s at
    ``times`` ``(N,)`` s: with ``voltages`` ``(N, 2)`` V at the same times, kS, kV, kA per
    channel; with ``commands`` ``(M, 2)`` rad/s held from ``command_times`` ``(M,)``, the
    velocity response (``accelerations``: the limits tried, rad/s^2). ``ValueError`` when
    neither is given, or names what the log lacks."""
    if voltages is None and commands is None:
        raise ValueError(
            "a drive is identified from its voltages (kS, kV, kA) or its commands (the "
            "velocity response): the log has neither"
        )
    speeds = np.asarray(velocities, dtype=float)
    drivetrain = None
    if voltages is not None:
        radii = np.array([robot.left_wheel_radius, robot.right_wheel_radius])
        drivetrain = identify_drivetrain(times, voltages, speeds * radii)
    response = None
    if commands is not None:
        response = identify_velocity_response(
            times, speeds, command_times, commands, accelerations=accelerations
        )
    return DriveIdentification(drivetrain, response)
