"""Synthetic streams as files: a robot's streams as a ROS 2 bag or MCAP file (what a robot
would have recorded, read back by ``diffdrive.io.ros`` and rosbags), or its wheels, gyro,
commands and truth as a wheel-log table (``diffdrive.io.read_run`` reads it)."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np

from diffdrive._validate import finite
from diffdrive.atomic import atomic_write
from diffdrive.sensors.absolute import AbsoluteReadings
from diffdrive.sensors.commands import Commands
from diffdrive.sensors.encoders import EncoderReadings
from diffdrive.sensors.gyro import GyroReadings

__all__ = ["bag_time_offset", "streams_of", "write_bag", "write_table"]


def _wheel_angles(encoders: EncoderReadings, robot: int) -> np.ndarray:
    """Robot ``robot``'s wheel angles ``(T+1, 2)`` rad as a driver publishes them: counts
    through their roll-overs, times the angle of a count."""
    run = encoders.run(robot)
    if run.kind == "angle":
        return run.wheels
    increments = run.increments(counter_bits=encoders.model.counter_bits)
    assert run.ticks_per_revolution is not None
    first = run.wheels[0].astype(np.float64) * (2.0 * math.pi / run.ticks_per_revolution)
    return first + np.concatenate([np.zeros((1, 2)), np.cumsum(increments, axis=0)])


def streams_of(
    robot: int = 0,
    *,
    encoders: EncoderReadings | None = None,
    gyro: GyroReadings | None = None,
    absolute: AbsoluteReadings | None = None,
    commands: Commands | None = None,
    origin: tuple[float, float, float] | None = None,
    truth: tuple[object, object] | None = None,
    time_offset: float = 0.0,
):
    """Robot ``robot``'s streams as ``diffdrive.io.ros.Stream``s: ``/joint_states``,
    ``/imu/data``, ``/pose`` (or, for a position sensor with an ``origin``, ``/fix``, in
    latitude and longitude, with its covariance) recorded when it arrives, ``/cmd_vel``, and
    the ``truth`` ``(times (T+1,), poses (T+1, 3))`` as ``nav_msgs/Odometry`` on
    ``/ground_truth`` (``world -> base_link``; each pose with the twist of the interval ending
    there, the first with the first's; covariances zero: exact); every time plus
    ``time_offset`` (s)."""
    from diffdrive.io.ros import Stream

    streams = _streams(robot, encoders, gyro, absolute, commands, origin, Stream)
    if truth is not None:
        streams.append(_truth_stream(*truth, Stream))
    return _shifted(streams, time_offset)


def _truth_stream(times, poses, Stream):
    """The trajectory as ``nav_msgs/Odometry`` rows ``[x, y, theta, vx, vy, omega]``."""
    from diffdrive import batch

    times, poses = np.asarray(times, dtype=float), np.asarray(poses, dtype=float)
    if poses.ndim != 2:
        raise ValueError(f"truth: one robot's poses (T+1, 3), got {poses.shape}")
    moves = batch.log(batch.relative_to(poses[1:], poses[:-1])) / np.diff(times)[:, None]
    twists = np.concatenate([moves[:1], moves])
    values = np.column_stack([poses, twists])
    return Stream("odometry", "/ground_truth", times, values, frame="world")


def _shifted(streams: list, offset: float) -> list:
    """``streams`` with ``offset`` s added to every stamp and record time."""
    offset = finite("time_offset", offset)
    if not offset:
        return streams
    return [
        replace(
            stream,
            times=stream.times + offset,
            recorded=None if stream.recorded is None else stream.recorded + offset,
        )
        for stream in streams
    ]


def _streams(robot, encoders, gyro, absolute, commands, origin, Stream):

    streams = []
    if encoders is not None:
        keep = encoders.kept[robot]
        angles = _wheel_angles(encoders, robot)
        streams.append(Stream("joints", "/joint_states", encoders.times[keep], angles))
    if gyro is not None:
        rates = gyro.angular_velocity[robot]
        streams.append(Stream("imu", "/imu/data", gyro.times, rates, frame="imu_link"))
    if absolute is not None:
        keep = absolute.kept[robot]
        times, arrival = absolute.times[keep], absolute.arrival[keep]
        if np.isnan(absolute.poses[robot, :, 2]).all():
            if origin is None:
                raise ValueError("a position sensor's fixes need the origin (lat, lon, height)")
            fixes = absolute.geodetic(origin)[robot][keep]
            sigma_x, sigma_y, _ = absolute.model.sigma
            # East, north, up (m^2): the synthetic fixes' height is exact.
            covariance = np.diag([sigma_x**2, sigma_y**2, 0.0])
            fix = Stream(
                "fix", "/fix", times, fixes, "gps", covariance=covariance, recorded=arrival
            )
            streams.append(fix)
        else:
            poses = absolute.poses[robot][keep]
            sigma = np.diag(np.square(absolute.model.sigma))
            pose = Stream("pose", "/pose", times, poses, "map", covariance=sigma, recorded=arrival)
            streams.append(pose)
    if commands is not None:
        twists = commands.twists[robot if len(commands.twists) > 1 else 0]
        streams.append(Stream("twist", "/cmd_vel", commands.times[:-1], twists))
    return streams


def write_bag(
    path: str | Path, robot: int = 0, *, format=None, time_offset: float | None = None, **readings
) -> Path:
    """Robot ``robot``'s streams (``streams_of``'s ``readings``, the ``truth`` among them) in
    one MCAP file or ROS 2 bag (``format``, default by the suffix: ``.mcap``, else a bag
    folder). ROS reads a stamp of 0 as unset: ``time_offset`` (s) is added to every time, the
    truth's too, by default 1 s when the trajectory starts at 0 (as ``simulate``'s do) and 0
    otherwise."""
    from diffdrive.io.ros import write_streams

    streams = streams_of(robot, **readings)
    if time_offset is None:  # from the streams' own first stamps
        starts = [stream.times[0] for stream in streams if len(stream.times)]
        time_offset = bag_time_offset(min(starts) if starts else 1.0)
    return write_streams(path, _shifted(streams, time_offset), format)


def bag_time_offset(first: float) -> float:
    """What ``write_bag`` adds to the times of streams whose first stamp is ``first`` (s): 1 s
    when it is 0 or before (ROS reads a stamp of 0 as unset), else 0."""
    return 1.0 if first <= 0.0 else 0.0


def write_table(
    path: str | Path,
    encoders: EncoderReadings,
    robot: int = 0,
    *,
    gyro: GyroReadings | None = None,
    commands: Commands | None = None,
    time_offset: float = 0.0,
) -> Path:
    """Robot ``robot``'s encoder rows as a wheel-log table (CSV): ``t`` (the readings' times
    plus ``time_offset`` s, as ``write_bag`` stamps them), the wheel columns (counts, or angles
    in rad), the truth ``x, y, theta``, and where given the gyro's yaw rate ``gyro_z`` and the
    commanded wheel velocities, sampled with the encoders."""
    keep = encoders.kept[robot]
    run = encoders.run(robot)
    kind = "ticks" if run.kind == "ticks" else "angle"
    columns = {"t": run.times + finite("time_offset", time_offset)}
    columns[f"left_{kind}"], columns[f"right_{kind}"] = run.wheels[:, 0], run.wheels[:, 1]
    assert run.truth is not None
    columns.update(x=run.truth[:, 0], y=run.truth[:, 1], theta=run.truth[:, 2])
    if gyro is not None:
        if not np.array_equal(gyro.times, encoders.times):
            raise ValueError("the gyro must be sampled with the encoders to share their table")
        columns["gyro_z"] = gyro.rates[robot][keep]
    if commands is not None:
        wheels = commands.wheels[robot if len(commands.wheels) > 1 else 0]
        held = np.concatenate([wheels, wheels[-1:]])[keep]  # the last row's is not used
        columns["left_command"], columns["right_command"] = held[:, 0], held[:, 1]
    with atomic_write(path) as stream:
        stream.write(",".join(columns) + "\n")
        for row in zip(*columns.values(), strict=True):
            stream.write(",".join(_cell(value) for value in row) + "\n")
    return Path(path)


def _cell(value) -> str:
    """A number as text that reads back exactly (counts as integers)."""
    if isinstance(value, np.integer):
        return str(int(value))
    return repr(float(value))
