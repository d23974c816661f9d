"""``Run``: what a robot recorded of its wheels, with ground truth where there is one.

One type for every source: a wheel-log table (``diffdrive.io.logs``), an OptiOdom run file
(``diffdrive.io.optiodom``), a bag's ``sensor_msgs/JointState`` topic (``diffdrive.io.ros``),
or wheel-angle increments in memory (``Run.from_increments``). ``diffdrive.io.read.read_run``
reads any of the files. The wheels are one of

- ``"ticks"``: absolute counter readings (whole counts, read exactly);
- ``"angle"``: accumulated wheel angles, rad;
- ``"velocity"``: wheel velocities, rad/s, each **held from its row's time until the next
  row's** (the last row's is not used). Every command reads them this way.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np

from diffdrive.encoders import count_changes
from diffdrive.errors import TableError
from diffdrive.model import Robot

__all__ = ["RIM_SPEED_LIMIT", "WHEEL_COLUMNS", "Run", "WheelKind", "narrower_counter"]

RIM_SPEED_LIMIT = 50.0
"""The rim speed (m/s) past which a wheel-speed jump is taken for a misread log, not motion, unless
the user sets the limit (``max_wheel_speed``, ``--max-wheel-speed``)."""

WheelKind = Literal["ticks", "angle", "velocity"]
"""What a log's wheel columns hold: counter ``"ticks"``, angles (rad) or velocities (rad/s)."""
WHEEL_COLUMNS: dict[WheelKind, tuple[str, str]] = {
    "ticks": ("left_ticks", "right_ticks"),
    "angle": ("left_angle", "right_angle"),
    "velocity": ("left_velocity", "right_velocity"),
}
"""The wheel columns' names of each ``WheelKind``, left then right."""


@dataclass(frozen=True, eq=False)
class Run:
    """A run: ``times`` ``(T+1,)`` s; ``wheels`` ``(T+1, 2)`` ``[left, right]`` of the
    ``kind`` (counts as int64 or uint64, rad, or rad/s); ``truth`` ``(T+1, 3)`` or None.

    ``source`` names where it came from and ``lines`` the line of each row in it (None when
    unknown), for messages; ``ticks_per_revolution`` is the encoders' resolution when the
    format fixes it; ``gyro_rates`` ``(T+1,)`` the body yaw rate (rad/s) of a gyro, and
    ``commands`` ``(T+1, 2)`` the commanded wheel velocities (rad/s, held until the next
    row), or None; ``reported`` ``(T+1, 2)`` the body's ``(v, omega)`` (m/s, rad/s) the source
    states at each row (a drive controller's ``Odometry``), or None.
    """

    times: np.ndarray
    kind: WheelKind
    wheels: np.ndarray
    truth: np.ndarray | None
    source: str
    lines: np.ndarray | None = None
    ticks_per_revolution: float | None = None
    gyro_rates: np.ndarray | None = None
    commands: np.ndarray | None = None
    voltages: np.ndarray | None = None
    reported: np.ndarray | None = None

    @classmethod
    def from_increments(
        cls,
        increments: object,
        truth: object = None,
        times: object = None,
        source: str = "increments",
    ) -> Run:
        """A run of wheel-angle ``increments`` ``(T, 2)`` rad (accumulated from 0), with
        ``truth`` ``(T+1, 3)`` and ``times`` ``(T+1,)`` s (None: one second a step)."""
        steps = np.asarray(increments, dtype=float)
        if steps.ndim != 2 or steps.shape[1] != 2:
            raise ValueError(f"{source}: increments must be (T, 2), got {steps.shape}")
        wheels = np.concatenate([np.zeros((1, 2)), np.cumsum(steps, axis=0)])
        stamps = np.arange(len(wheels), dtype=float) if times is None else np.asarray(times, float)
        if stamps.shape != (len(wheels),):
            raise ValueError(
                f"{source}: times must be (T+1,) = ({len(wheels)},), got {stamps.shape}"
            )
        poses = None if truth is None else np.asarray(truth, dtype=float)
        if poses is not None and poses.shape != (len(wheels), 3):
            raise ValueError(
                f"{source}: ground truth must be (T+1, 3) = {(len(wheels), 3)}, got {poses.shape}"
            )
        return cls(stamps, "angle", wheels, poses, source)

    def where(self, row: int) -> str:
        """``source:line`` of row ``row`` (0-based), for messages."""
        if self.lines is None:
            return f"{self.source}, row {row + 1}"
        return f"{self.source}:{int(self.lines[row])}"

    def rows(self, keep: np.ndarray) -> Run:
        """The run cut to the rows ``keep`` selects (a boolean mask or indices)."""

        def cut(values):
            return None if values is None else values[keep]

        return replace(
            self,
            times=self.times[keep],
            wheels=self.wheels[keep],
            truth=cut(self.truth),
            lines=cut(self.lines),
            gyro_rates=cut(self.gyro_rates),
            commands=cut(self.commands),
            voltages=cut(self.voltages),
            reported=cut(self.reported),
        )

    def increments(
        self, ticks_per_revolution: float | None = None, counter_bits: int | None = None
    ) -> np.ndarray:
        """The wheel angles turned over each interval, ``(T, 2)`` rad.

        Ticks need ``ticks_per_revolution`` (or the run's own) and go through roll-overs of
        ``counter_bits``-bit counters; velocities are held from each row to the next.
        """
        if counter_bits is not None and self.kind != "ticks":
            raise TableError(
                f"{self.source}: a counter width ({counter_bits} bits, --counter-bits) reads "
                f"roll-overs of counter readings, but the log holds wheel {self.kind}s"
            )
        if self.kind == "velocity":
            return self.wheels[:-1] * np.diff(self.times)[:, None]
        if self.kind == "angle":
            return np.diff(self.wheels, axis=0)
        ticks = self.ticks_per_revolution if ticks_per_revolution is None else ticks_per_revolution
        if ticks is not None and not (math.isfinite(ticks) and ticks > 0):
            raise TableError(f"ticks per revolution must be finite and > 0, got {ticks!r}")
        if ticks is None:
            raise TableError(
                f"{self.source}: ticks need the counts per wheel revolution: give "
                "--ticks-per-revolution (or ticks_per_revolution in the robot file)"
            )
        radians = 2.0 * math.pi / ticks
        if not math.isfinite(radians):
            raise TableError(f"ticks per revolution {ticks!r} gives no finite angle per count")
        return count_changes(self.wheels, counter_bits) * radians

    def wheel_velocities(
        self, ticks_per_revolution: float | None = None, counter_bits: int | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """The wheels' measured velocities ``(N, 2)`` rad/s and their times ``(N,)`` s: a
        velocity log's own rows (the last, held over nothing, left out), else each interval's
        turn over its duration, at the interval's middle."""
        if self.kind == "velocity":
            return self.times[:-1], self.wheels[:-1].astype(float)
        increments = self.increments(ticks_per_revolution, counter_bits)
        middles = 0.5 * (self.times[1:] + self.times[:-1])
        return middles, increments / np.diff(self.times)[:, None]

    def start_pose(self) -> np.ndarray:
        """Where the run starts, ``(3,)``: its first ground-truth pose, else the origin."""
        return np.zeros(3) if self.truth is None else self.truth[0]

    def checked_increments(
        self,
        robot: Robot,
        ticks_per_revolution: float | None = None,
        counter_bits: int | None = None,
        max_wheel_speed: float | None = None,
    ) -> tuple[np.ndarray, str]:
        """``increments()`` ``(T, 2)`` rad, refused when they cannot be the robot's, and a line
        on the largest wheel speed.

        Without ``max_wheel_speed`` (rad/s), ticks that fit a narrower counter than
        ``counter_bits`` and jump by more than half its range are refused (a roll-over read
        with the wrong width), and so is a wheel faster than ``RIM_SPEED_LIMIT`` m/s at its
        rim; ``TableError`` names the row's file and line.
        """
        increments = self.increments(ticks_per_revolution, counter_bits)
        speed, side, row = self.largest_wheel_speed(increments)
        drive = robot.equivalent
        radius = drive.left_wheel_radius if side == "left" else drive.right_wheel_radius
        line = (
            f"largest wheel speed in the log: {speed:.4g} rad/s ({speed * radius:.3g} m/s at the "
            f"rim), {side} wheel, {self.where(row)}"
        )
        narrower = narrower_counter(self, counter_bits) if max_wheel_speed is None else None
        if narrower is not None:
            bits, row = narrower
            jump = count_changes(self.wheels[row - 1 : row + 1], counter_bits)
            read_as = f"{counter_bits}-bit" if counter_bits else "never rolling over"
            raise TableError(
                f"{self.where(row)}: the counters jump by {int(np.abs(jump).max())} counts, yet "
                f"every reading fits {bits} bits: a {bits}-bit counter rolling over, read as "
                f"{read_as}? Give --counter-bits {bits} (counter_bits={bits}); or "
                "--max-wheel-speed to take the jump as read"
            )
        if max_wheel_speed is None and speed * radius > RIM_SPEED_LIMIT:
            hint = (
                " a wrong --counter-bits or --ticks-per-revolution?" if self.kind == "ticks" else ""
            )
            raise TableError(
                f"{self.where(row)}: the {side} wheel would turn at {speed:.4g} rad/s "
                f"({speed * radius:.3g} m/s at its rim), faster than any wheeled robot drives;"
                f"{hint} Give --max-wheel-speed (max_wheel_speed) to set the limit yourself"
            )
        return increments, line

    def largest_wheel_speed(self, increments: np.ndarray) -> tuple[float, str, int]:
        """The fastest wheel over any interval, from this run's ``increments()`` ``(T, 2)``:
        ``(rad/s, "left" or "right", row)``, where ``row`` (0-based) ends the interval."""
        speeds = np.abs(increments) / np.diff(self.times)[:, None]
        interval, side = np.unravel_index(int(np.argmax(speeds)), speeds.shape)
        return float(speeds[interval, side]), ("left", "right")[side], int(interval) + 1


def narrower_counter(run: Run, counter_bits: int | None) -> tuple[int, int] | None:
    """``(bits, row)`` when a ticks run looks read with the wrong counter width.

    That is when every reading fits a counter of fewer ``bits`` than ``counter_bits`` (or
    than 64 with None) and some change, ending at ``row``, is more than half that narrower
    range: on the narrower counter it is a roll-over, not a jump of the wheel.
    """
    if run.kind != "ticks" or len(run.wheels) < 2:
        return None
    low, high = int(run.wheels.min()), int(run.wheels.max())
    if low >= 0:
        narrow = max(high.bit_length(), 2)
    else:
        narrow = max(high.bit_length(), (-low - 1).bit_length()) + 1
    if narrow >= (counter_bits or 64):
        return None
    changes = np.abs(count_changes(run.wheels, counter_bits))
    rows = np.flatnonzero(np.any(changes > 2 ** (narrow - 1), axis=1))
    return (narrow, int(rows[0]) + 1) if rows.size else None
