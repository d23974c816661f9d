"""Wheel-log tables: a robot's wheels as a table of numbers (``diffdrive.io.tables``).

A time column ``t`` and one pair of wheel columns (``diffdrive.io.run.WHEEL_COLUMNS``:
``left_ticks, right_ticks``, ``left_angle, right_angle`` or ``left_velocity,
right_velocity``), and optionally ``x, y, theta`` (ground truth), ``gyro_z`` (the body yaw
rate of a gyro, rad/s), ``left_command, right_command`` (the commanded wheel velocities,
rad/s) and ``left_voltage, right_voltage`` (V, as SysId logs them), each pair whole. A file
without a header is read as an OptiOdom run file (``diffdrive.io.optiodom``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from diffdrive.io.optiodom import read_optiodom_run
from diffdrive.io.run import WHEEL_COLUMNS, Run
from diffdrive.io.tables import (
    Table,
    TableError,
    is_number,
    read_header,
    read_table,
    refuse_a_slow_wheel_log,
)

__all__ = ["read_log"]

_TRUTH = ("x", "y", "theta")
_COMMANDS = ("left_command", "right_command")
_VOLTAGES = ("left_voltage", "right_voltage")


def read_log(path: str | Path, time_unit: str | None = None) -> Run:
    """The run in a wheel-log table or an OptiOdom run file (see the module).

    ``time_unit`` is the unit of ``t`` (``s``, ``ms``, ``us``, ``ns``; None: seconds, refused
    when plainly not, as a wheel log of 100 rows or more a second or more apart is).
    ``TableError`` names the file, line and column of what is wrong.
    """
    path = Path(path)
    header = read_header(path)
    if all(is_number(name) for name in header):
        return read_optiodom_run(path, time_unit)
    kind = next((k for k, (left, _) in WHEEL_COLUMNS.items() if left in header), None)
    if kind is None:
        wanted = " or ".join(", ".join(pair) for pair in WHEEL_COLUMNS.values())
        raise TableError(
            f"{path}:1: missing wheel columns: {wanted} (the header has: {', '.join(header)})"
        )
    columns = WHEEL_COLUMNS[kind]
    integers = columns if kind == "ticks" else ()
    table = read_table(
        path,
        ["t", *columns],
        (*_TRUTH, "gyro_z", *_COMMANDS, *_VOLTAGES),
        integers=integers,
        time_unit=time_unit,
    )
    commands, voltages = _pair(table, _COMMANDS, path), _pair(table, _VOLTAGES, path)
    if len(table["t"]) < 2:
        raise TableError(f"{path}: a log needs at least 2 rows")
    if time_unit is None:
        refuse_a_slow_wheel_log(table["t"], "t", path)
    left, right = table[columns[0]], table[columns[1]]
    if left.dtype != right.dtype and kind == "ticks":
        # One column needs uint64 (readings of 2^63 and more): only a 64-bit counter reads
        # so, and modulo 2^64 the negative readings of the other are the same counts.
        left, right = left.astype(np.uint64), right.astype(np.uint64)
    return Run(
        table["t"],
        kind,
        np.column_stack([left, right]),
        _truth(table, path),
        str(path),
        table.lines,
        gyro_rates=table.get("gyro_z"),
        commands=commands,
        voltages=voltages,
    )


def _pair(table: Table, names: tuple[str, str], path: Path) -> np.ndarray | None:
    """The two columns ``names`` side by side, None when neither is there; one alone is
    refused (the other wheel's would be guessed)."""
    present = [name for name in names if name in table]
    if not present:
        return None
    if len(present) == 1:
        missing = next(name for name in names if name not in table)
        raise TableError(f"{path}:1: {present[0]} needs {missing} beside it")
    return np.column_stack([table[name] for name in names])


def _truth(table: Table, path: Path) -> np.ndarray | None:
    present = [name for name in _TRUTH if name in table]
    if not present:
        return None
    if len(present) < 3:
        missing = next(name for name in _TRUTH if name not in table)
        raise TableError(f"{path}:1: ground truth needs x, y and theta; {missing!r} is missing")
    return np.column_stack([table[name] for name in _TRUTH])
