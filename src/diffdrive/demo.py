"""Built-in example robots, so that every entry point has something to run on."""

from __future__ import annotations

import numpy as np

from diffdrive.model import DiffDrive


def example_robot() -> DiffDrive:
    """A small indoor robot: the OptiOdom platform's nominal geometry (84 mm wheels, 0.2 m)."""
    return DiffDrive(wheel_radius=0.042, track_width=0.200)


EXAMPLE_DURATION = 20.0
"""How long the built-in driving history lasts, s."""


def example_wheel_velocities(t: np.ndarray) -> np.ndarray:
    """A built-in driving history, rad/s, for times ``t`` ``(T,)`` in s -> ``(T, 2)``.

    Drives off, weaves left and right with a growing amplitude, and turns in place at the end.
    """
    t = np.asarray(t, dtype=np.float64)
    cruise = 8.0 * np.clip(t / 2.0, 0.0, 1.0) * (t < 16.0)
    weave = (2.0 + 0.2 * t) * np.sin(2.0 * np.pi * t / 8.0) * (t < 16.0)
    spin = 4.0 * (t >= 16.0)
    return np.stack([cruise - weave - spin, cruise + weave + spin], axis=-1)


EXAMPLE_TICKS_PER_REVOLUTION = 2796.8
"""The built-in encoder log's counts per wheel revolution: the OptiOdom robot's (43.7:1 gear,
64 counts per motor revolution)."""


def example_encoder_log(rate: float = 20.0) -> dict[str, np.ndarray]:
    """An encoder log of the built-in driving history, as ``diffdrive odometry`` reads one.

    Columns ``t`` (s, at ``rate`` Hz), ``left_ticks`` and ``right_ticks`` (whole counter
    readings of ``EXAMPLE_TICKS_PER_REVOLUTION`` per turn, rounded down as a counter counts),
    and the ground truth ``x``, ``y``, ``theta`` from an exact simulation at 1 ms steps.
    """
    from diffdrive.simulation import simulate

    fine = simulate(example_robot(), example_wheel_velocities, dt=1e-3, duration=EXAMPLE_DURATION)
    every = round(1e3 / rate)
    angles = fine.wheel_positions[::every]
    ticks = np.floor(angles * EXAMPLE_TICKS_PER_REVOLUTION / (2 * np.pi))
    poses = fine.poses[::every]
    return {
        "t": fine.times[::every],
        "left_ticks": ticks[:, 0],
        "right_ticks": ticks[:, 1],
        "x": poses[:, 0],
        "y": poses[:, 1],
        "theta": poses[:, 2],
    }


def example_log():
    """``example_encoder_log`` as the ``Run`` every command reads (int64 counts)."""
    from diffdrive.io.run import Run

    log = example_encoder_log()
    return Run(
        log["t"],
        "ticks",
        np.column_stack([log["left_ticks"], log["right_ticks"]]).astype(np.int64),
        np.column_stack([log["x"], log["y"], log["theta"]]),
        "the built-in encoder log",
        ticks_per_revolution=EXAMPLE_TICKS_PER_REVOLUTION,
    )
