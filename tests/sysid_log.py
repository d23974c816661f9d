"""A SysId-like voltage log: a quasistatic ramp up and down, then steps, driving straight and
then turning both ways, through a drive of known feedforward; the wheels' speeds with a little
noise (``tests/test_export.py``, and the calibration guide's shell block)."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def write_sysid(path: Path, radius: float, seed: int = 3) -> None:
    """``path`` as ``diffdrive identify`` reads it (``t``, each wheel's velocity in rad/s and
    voltage in V), of a drive with kS 1 V, kV 3 V s/m and kA 0.5 V s^2/m of the wheels'
    surface speed on wheels of ``radius`` m."""
    from diffdrive.dynamics import DriveModel, Feedforward

    motor = DriveModel(feedforward=Feedforward(1.0, 3.0 * radius, 0.5 * radius))  # per rad/s
    t = np.arange(0.0, 40.0, 0.01)
    ramp = np.where(t < 10, 0.25 * t, -0.25 * (t - 10))
    steps = np.where(t < 25, 7.0, -7.0)
    straight = np.where(t < 20, ramp, steps)
    volts = np.column_stack([straight, straight])
    volts = np.concatenate([volts, volts * np.array([-1.0, 1.0])])  # then turning both ways
    times = np.arange(len(volts)) * 0.01
    wheels = motor.wheel_velocities(times, times, volts)
    wheels += np.random.default_rng(seed).normal(0, 0.002 / radius, wheels.shape)
    columns = [times, wheels[:, 0], wheels[:, 1], volts[:, 0], volts[:, 1]]
    with open(path, "w") as out:
        out.write("t,left_velocity,right_velocity,left_voltage,right_voltage\n")
        out.writelines(
            ",".join(repr(float(v)) for v in row) + "\n" for row in zip(*columns, strict=True)
        )
