"""OptiOdom run files: the differential-drive data of Sousa et al. (2022).

A run file has no header and one row per odometry cycle (20 Hz): ``t, x, y, theta, ticks_right,
ticks_left``. The ground truth (OptiTrack) is continuous in ``theta``; the ticks in row ``i``
were counted over ``(t[i-1], t[i]]`` and row 0 holds zeros. Note the order: right, then left.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from diffdrive.io.run import Run
from diffdrive.io.tables import TableError, number_row, text_lines, times_in_seconds
from diffdrive.model import DiffDrive

__all__ = [
    "OPTIODOM_TICKS_PER_REVOLUTION",
    "optiodom_robot",
    "read_optiodom_run",
]

# 43.7:1 gearbox times 64 encoder counts per motor revolution.
OPTIODOM_TICKS_PER_REVOLUTION = 43.7 * 64


def optiodom_robot(
    track_width: float = 0.2, right_diameter: float = 0.084, left_diameter: float = 0.084
) -> DiffDrive:
    """The OptiOdom robot from the authors' parameters ``L``, ``Dr``, ``Dl`` (m)."""
    return DiffDrive(
        left_wheel_radius=left_diameter / 2,
        right_wheel_radius=right_diameter / 2,
        track_width=track_width,
    )


def read_optiodom_run(path: str | Path, time_unit: str | None = None) -> Run:
    """The ``Run`` of one ``<experiment>_run-NN.csv``: absolute counter readings (0 at the
    start, ``OPTIODOM_TICKS_PER_REVOLUTION`` a turn) and the ground truth.

    ``time_unit`` as in ``diffdrive.io.tables``; ``TableError`` names the file and line.
    """
    path = Path(path)
    rows: list[list[float]] = []
    lines: list[int] = []
    for number, line in text_lines(path):
        fields = line.strip().split(",")
        if fields == [""]:
            continue
        row = number_row(path, number, fields, 6, "an OptiOdom")
        if rows and row[0] <= rows[-1][0]:
            raise TableError(f"{path}:{number}: time {row[0]} does not increase")
        if row[4] != round(row[4]) or row[5] != round(row[5]):
            raise TableError(f"{path}:{number}: ticks must be whole counts")
        rows.append(row)
        lines.append(number)
    if len(rows) < 2:
        raise TableError(f"{path}: a run needs at least 2 rows, got {len(rows)}")
    table = np.array(rows)
    # The file has right, then left, and counts over each cycle.
    counters = np.cumsum(table[:, [5, 4]].astype(np.int64), axis=0)
    columns = {"t": table[:, 0]}
    times_in_seconds(columns, "t", time_unit, path)
    return Run(
        columns["t"],
        "ticks",
        counters,
        table[:, 1:4],
        str(path),
        np.array(lines),
        ticks_per_revolution=OPTIODOM_TICKS_PER_REVOLUTION,
    )
