"""Wheel logs: what a robot recorded of its wheels, with ground truth where there is one.

One type, ``WheelLog``, for every format the command line reads: a table (``diffdrive.files``)
with a time column ``t`` and one pair of wheel columns, and optionally ``x, y, theta`` (ground
truth), ``gyro_z`` (the body yaw rate of a gyro, rad/s) and ``left_command, right_command``
(the commanded wheel velocities, rad/s), or an OptiOdom run file
(``diffdrive.datasets``). The wheel columns are one of

- ``left_ticks, right_ticks``: absolute counter readings (whole counts, read exactly);
- ``left_angle, right_angle``: accumulated wheel angles, rad;
- ``left_velocity, right_velocity``: wheel velocities, rad/s, each **held from its row's time
  until the next row's** (the last row's is not used). Every command reads them this way.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

from diffdrive.encoders import count_changes
from diffdrive.files import (
    Table,
    TableError,
    is_number,
    read_header,
    read_table,
    times_in_seconds,
)

__all__ = ["WHEEL_COLUMNS", "WheelLog", "narrower_counter", "read_log"]

WheelKind = Literal["ticks", "angle", "velocity"]
WHEEL_COLUMNS: dict[WheelKind, tuple[str, str]] = {
    "ticks": ("left_ticks", "right_ticks"),
    "angle": ("left_angle", "right_angle"),
    "velocity": ("left_velocity", "right_velocity"),
}
_TRUTH = ("x", "y", "theta")
_COMMANDS = ("left_command", "right_command")


@dataclass(frozen=True, eq=False)
class WheelLog:
    """A wheel log: ``times`` ``(T+1,)`` s; ``wheels`` ``(T+1, 2)`` ``[left, right]`` of the
    ``kind`` (counts as int64 or uint64, rad, or rad/s); ``truth`` ``(T+1, 3)`` or None.

    ``source`` names where it came from and ``lines`` the line of each row in it (None when
    unknown), for messages; ``ticks_per_revolution`` is the encoders' resolution when the
    format fixes it; ``gyro_rates`` ``(T+1,)`` the body yaw rate (rad/s) of a ``gyro_z``
    column, and ``commands`` ``(T+1, 2)`` the commanded wheel velocities (rad/s, held until
    the next row) of ``left_command, right_command`` columns, or None.
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

    def where(self, row: int) -> str:
        """``source:line`` of row ``row`` (0-based), for messages."""
        if self.lines is None:
            return f"{self.source}, row {row + 1}"
        return f"{self.source}:{int(self.lines[row])}"

    def increments(
        self, ticks_per_revolution: float | None = None, counter_bits: int | None = None
    ) -> np.ndarray:
        """The wheel angles turned over each interval, ``(T, 2)`` rad.

        Ticks need ``ticks_per_revolution`` (or the log's own) and go through roll-overs of
        ``counter_bits``-bit counters; velocities are held from each row to the next.
        """
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

    def largest_wheel_speed(self, increments: np.ndarray) -> tuple[float, str, int]:
        """The fastest wheel over any interval, from this log's ``increments()`` ``(T, 2)``:
        ``(rad/s, "left" or "right", row)``, where ``row`` (0-based) ends the interval."""
        speeds = np.abs(increments) / np.diff(self.times)[:, None]
        interval, side = np.unravel_index(int(np.argmax(speeds)), speeds.shape)
        return float(speeds[interval, side]), ("left", "right")[side], int(interval) + 1


def narrower_counter(log: WheelLog, counter_bits: int | None) -> tuple[int, int] | None:
    """``(bits, row)`` when a ticks log looks read with the wrong counter width.

    That is when every reading fits a counter of fewer ``bits`` than ``counter_bits`` (or
    than 64 with None) and some change, ending at ``row``, is more than half that narrower
    range: on the narrower counter it is a roll-over, not a jump of the wheel.
    """
    if log.kind != "ticks" or len(log.wheels) < 2:
        return None
    low, high = int(log.wheels.min()), int(log.wheels.max())
    if low >= 0:
        narrow = max(high.bit_length(), 2)
    else:
        narrow = max(high.bit_length(), (-low - 1).bit_length()) + 1
    if narrow >= (counter_bits or 64):
        return None
    changes = np.abs(count_changes(log.wheels, counter_bits))
    rows = np.flatnonzero(np.any(changes > 2 ** (narrow - 1), axis=1))
    return (narrow, int(rows[0]) + 1) if rows.size else None


def read_log(path: str | Path, time_unit: str | None = None) -> WheelLog:
    """A wheel log from a table or an OptiOdom run file (see the module).

    ``time_unit`` is the unit of ``t`` (``s``, ``ms``, ``us``, ``ns``; None: seconds, refused
    when plainly not). ``TableError`` names the file, line and column of what is wrong.
    """
    path = Path(path)
    header = read_header(path)
    if all(is_number(name) for name in header):
        return _optiodom_log(path, time_unit)
    kind = next((k for k, (left, _) in WHEEL_COLUMNS.items() if left in header), None)
    if kind is None:
        wanted = " or ".join(", ".join(pair) for pair in WHEEL_COLUMNS.values())
        raise TableError(
            f"{path}:1: missing wheel columns: {wanted} (the header has: {', '.join(header)})"
        )
    columns = WHEEL_COLUMNS[kind]
    integers = columns if kind == "ticks" else ()
    table = read_table(path, ["t", *columns], (*_TRUTH, "gyro_z", *_COMMANDS),
                       integers=integers, time_unit=time_unit)  # fmt: skip
    commands = None
    if all(name in table for name in _COMMANDS):
        commands = np.column_stack([table[name] for name in _COMMANDS])
    if len(table["t"]) < 2:
        raise TableError(f"{path}: a log needs at least 2 rows")
    left, right = table[columns[0]], table[columns[1]]
    if left.dtype != right.dtype and kind == "ticks":
        # One column needs uint64 (readings of 2^63 and more): only a 64-bit counter reads
        # so, and modulo 2^64 the negative readings of the other are the same counts.
        left, right = left.astype(np.uint64), right.astype(np.uint64)
    return WheelLog(
        table["t"], kind, np.column_stack([left, right]), _truth(table, path), str(path),
        table.lines, gyro_rates=table.get("gyro_z"), commands=commands,
    )  # fmt: skip


def _truth(table: Table, path: Path) -> np.ndarray | None:
    present = [name for name in _TRUTH if name in table]
    if not present:
        return None
    if len(present) < 3:
        missing = next(name for name in _TRUTH if name not in table)
        raise TableError(f"{path}:1: ground truth needs x, y and theta; {missing!r} is missing")
    return np.column_stack([table[name] for name in _TRUTH])


def _optiodom_log(path: Path, time_unit: str | None) -> WheelLog:
    from diffdrive.datasets import OPTIODOM_TICKS_PER_REVOLUTION, read_optiodom_run

    try:
        run = read_optiodom_run(path)
    except ValueError as exc:
        raise TableError(str(exc)) from None
    columns = {"t": run.times.copy()}
    times_in_seconds(columns, "t", time_unit, path)
    return WheelLog(
        columns["t"], "ticks", run.counters, run.ground_truth, str(path),
        ticks_per_revolution=OPTIODOM_TICKS_PER_REVOLUTION,
    )  # fmt: skip
