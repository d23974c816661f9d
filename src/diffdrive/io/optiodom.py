"""OptiOdom run files: the differential-drive data of Sousa et al. (2022).

A run file has no header and one row per odometry cycle (20 Hz): ``t, x, y, theta, ticks_right,
ticks_left``. The ground truth (OptiTrack) is continuous in ``theta``; the ticks in row ``i``
were counted over ``(t[i-1], t[i]]`` and row 0 holds zeros. Note the order: right, then left.
"""

from __future__ import annotations

from datetime import datetime
from pathlib import Path

import numpy as np

from diffdrive.io.run import Run
from diffdrive.io.tables import TableError, number_row, text_lines, times_in_seconds
from diffdrive.model import DiffDrive

__all__ = [
    "OPTIODOM_TICKS_PER_REVOLUTION",
    "optiodom_robot",
    "optiodom_sessions",
    "read_optiodom_run",
]

# Experiments started less than this apart (h) were recorded in one sitting.
SESSION_GAP_HOURS = 12.0

OPTIODOM_TICKS_PER_REVOLUTION = 43.7 * 64
"""The OptiOdom robot's counts per wheel revolution: a 43.7:1 gearbox times 64 counts per motor
revolution."""


def optiodom_robot(
    track_width: float = 0.2, right_diameter: float = 0.084, left_diameter: float = 0.084
) -> DiffDrive:
    """The OptiOdom robot from the authors' parameters ``L``, ``Dr``, ``Dl`` (m)."""
    return DiffDrive(
        left_wheel_radius=left_diameter / 2,
        right_wheel_radius=right_diameter / 2,
        track_width=track_width,
    )


def optiodom_sessions(experiments) -> dict[str, str]:
    """Each experiment's session: its name is its start, ``ddmmyyyyHHMM``, and experiments
    started less than ``SESSION_GAP_HOURS`` after the one before share a session (one sitting
    across midnight is one), named by its first day, ``yyyy-mm-dd``. ``ValueError`` names an
    experiment whose name is no such time."""
    starts = {}
    for name in experiments:
        try:
            starts[name] = datetime.strptime(str(name), "%d%m%Y%H%M")
        except ValueError:
            raise ValueError(
                f"experiment {name!r}: an OptiOdom experiment is named by its start, "
                "ddmmyyyyHHMM (e.g. 231220200029)"
            ) from None
    sessions: dict[str, str] = {}
    ordered = sorted(starts, key=starts.__getitem__)
    for before, name in zip([None, *ordered], ordered, strict=False):
        gap = None if before is None else starts[name] - starts[before]
        if gap is None or gap.total_seconds() > 3600 * SESSION_GAP_HOURS:
            session = starts[name].strftime("%Y-%m-%d")
        sessions[name] = session
    return sessions


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
