"""A synthetic mixed drive for calibration against a reference: straights, arcs and turns in
place both ways, the wheels' readings and a camera's poses, with known parameters
(``tests/test_reference_calibration.py`` and ``benchmarks/bench_reference_calibration.py``)."""

from __future__ import annotations

import numpy as np

import diffdrive as dd
from diffdrive import sensors

NOMINAL = dd.DiffDrive(wheel_radius=0.05, track_width=0.3)
# The robot as it is: radii 0.5 % over and 0.3 % under, the track 1 % wide.
TRUE = dd.DiffDrive(left_wheel_radius=0.05025, right_wheel_radius=0.04985, track_width=0.303)
MOUNT = (0.15, -0.05, 0.1)  # the camera on the robot: x, y (m), yaw (rad)
CLOCK = 0.05  # s: the camera's stamps run this far ahead of the wheels'
K = 1e-5  # m: the wheels' random walk


def segments(rng: np.random.Generator, seconds: float, kinds: int = 3) -> np.ndarray:
    """Body twists ``(v, omega)`` per 0.01 s over ``seconds``: straights, arcs both ways and
    turns in place both ways, each 2-8 s (``kinds=1``: straights alone, at speeds of their
    own)."""
    twists = []
    while len(twists) < round(seconds / 0.01):
        kind = rng.integers(kinds)
        span = int(rng.uniform(2, 8) / 0.01)
        sign = rng.choice([-1.0, 1.0])
        if kind == 0:
            twist = (rng.uniform(0.3, 0.8), 0.0)
        elif kind == 1:
            twist = (rng.uniform(0.3, 0.6), sign * rng.uniform(0.3, 0.8))
        else:
            twist = (0.0, sign * rng.uniform(0.5, 1.0))
        twists.extend([twist] * span)
    # Eased over 0.3 s between segments, as a drive's acceleration limits would: a turn rate
    # that jumped would read late or early on any gyro sampled between the jumps.
    steps = np.array(twists[: round(seconds / 0.01)])
    kernel = np.ones(30) / 30
    padded = np.concatenate(
        [np.repeat(steps[:1], 15, axis=0), steps, np.repeat(steps[-1:], 14, axis=0)]
    )
    return np.column_stack([np.convolve(padded[:, i], kernel, mode="valid") for i in range(2)])


CAMERA = (0.02, 0.02, np.radians(1.0))  # m, m, rad: the camera's noise


def drive(seed: int, seconds: float = 300.0, sigma=CAMERA, period=0.1, kinds: int = 3):
    """``(times, increments, stamps, poses)``: the wheels' readings at 100 Hz of ``TRUE``
    driving a mixed path (``segments``' ``kinds``), and a camera at ``MOUNT`` with clock
    ``CLOCK`` every ``period`` s with noise ``sigma``, sampling between the wheels' (the path
    simulated at 1 kHz)."""
    return camera_and_gyro(seed, seconds, sigma, period, kinds)[:4]


def camera_and_gyro(seed: int, seconds: float = 300.0, sigma=CAMERA, period=0.1, kinds: int = 3):
    """``drive``'s, and a ``Gyro`` at 100 Hz along the same path with ``GYRO``'s terms."""
    rng = np.random.default_rng(seed)
    camera = sensors.AbsoluteModel(sigma=sigma, period=period, mount=MOUNT, clock_offset=CLOCK)
    times, increments, gyro, seen = _recorded(rng, seconds, kinds, camera)
    return times, increments, seen.times, seen.poses[0], gyro


def _recorded(rng: np.random.Generator, seconds: float, kinds: int, absolute):
    """``TRUE`` driving a mixed path at 1 kHz: the wheels' readings at 100 Hz, the gyro, and
    what the ``absolute`` sensor (an ``AbsoluteModel``) read, a few ms past the wheels'."""
    twists = np.repeat(segments(rng, seconds, kinds), 10, axis=0)
    body = np.column_stack([twists[:, 0], np.zeros(len(twists)), twists[:, 1]])
    wheels = dd.batch.to_wheel_velocities(TRUE, body)
    fine = np.arange(len(twists) + 1) * 0.001
    path = dd.simulate(TRUE, wheels, times=fine)
    times, poses = fine[::10], path.poses[::10]
    encoders = sensors.EncoderModel(wheel_noise=K)
    read = sensors.encoder_readings(TRUE, times, poses, encoders, seed=int(rng.integers(2**31)))
    phase = int(rng.integers(1, 10))  # ms past a wheel reading
    seen = sensors.absolute_readings(
        TRUE, fine[phase:], path.poses[phase:], absolute, seed=int(rng.integers(2**31))
    )
    gyro = _gyro(times, poses, int(rng.integers(2**31)))
    return times, np.diff(read.readings[0], axis=0), gyro, seen


def _gyro(times: np.ndarray, poses: np.ndarray, seed: int):
    """A gyro on ``TRUE`` along ``poses``: ``GYRO``'s scale, bias and clock, ``GYRO_ARW``."""
    from diffdrive.estimation import Gyro
    from diffdrive.sensor_noise import GyroNoise

    noise = GyroNoise(angle_random_walk=GYRO_ARW)
    model = sensors.GyroModel(bias=GYRO["bias"], scale=GYRO["scale"], noise=noise)
    rates = sensors.gyro_readings(TRUE, times, poses, model, seed=seed)
    return Gyro(times + GYRO["clock"], rates.rates[0])


ANTENNA = (-0.2, 0.1)  # the GPS antenna on the robot, m
GPS_CLOCK = 0.3  # s: the receiver's stamps run this far ahead of the wheels'
GPS_SIGMA = 0.5  # m
GYRO = {"scale": 0.01, "bias": 0.005, "clock": 0.02}  # relative, rad/s, s
GYRO_ARW = 2e-3  # rad/s/sqrt(Hz)


def gps_drive(seed: int, seconds: float = 300.0, period: float = 0.5):
    """``(times, increments, gyro, stamps, positions)``: the wheels at 100 Hz of ``TRUE``
    driving a mixed path, a gyro at 100 Hz with ``GYRO``'s scale, bias and clock and an angle
    random walk of ``GYRO_ARW``, and a GPS receiver at ``ANTENNA`` every ``period`` s with
    ``GPS_SIGMA`` of noise and clock ``GPS_CLOCK``."""
    rng = np.random.default_rng(seed)
    receiver = sensors.AbsoluteModel(
        sigma=(GPS_SIGMA, GPS_SIGMA, 0.0), period=period, position_only=True,
        mount=(*ANTENNA, 0.0), clock_offset=GPS_CLOCK,
    )  # fmt: skip
    times, increments, gyro, fixes = _recorded(rng, seconds, 3, receiver)
    return times, increments, gyro, fixes.times, fixes.poses[0][:, :2]
