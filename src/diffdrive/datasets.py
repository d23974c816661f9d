"""Readers for recorded runs: the OptiOdom differential-drive data (Sousa et al. 2022).

A run file has no header and one row per odometry cycle (20 Hz): ``t, x, y, theta, ticks_right,
ticks_left``. The ground truth (OptiTrack) is continuous in ``theta``; the ticks in row ``i``
were counted over ``(t[i-1], t[i]]`` and row 0 holds zeros. Note the order: right, then left.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from diffdrive.files import number_row, text_lines
from diffdrive.model import DiffDrive

__all__ = [
    "OPTIODOM_TICKS_PER_REVOLUTION",
    "OptiOdomRun",
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


@dataclass(frozen=True, eq=False)
class OptiOdomRun:
    """One run: ``times`` ``(T+1,)`` s, ``ground_truth`` ``(T+1, 3)`` ``[x, y, theta]``, and
    ``ticks`` ``(T+1, 2)`` ``[left, right]`` counted over each cycle (row 0 zeros)."""

    path: Path
    times: np.ndarray
    ground_truth: np.ndarray
    ticks: np.ndarray

    @property
    def counters(self) -> np.ndarray:
        """Absolute counter readings ``(T+1, 2)`` ``[left, right]``, 0 at the start."""
        return np.cumsum(self.ticks, axis=0)

    def wheel_angles(self) -> np.ndarray:
        """Accumulated wheel angles ``(T+1, 2)`` ``[left, right]``, rad."""
        return self.counters * (2.0 * math.pi / OPTIODOM_TICKS_PER_REVOLUTION)


def read_optiodom_run(path: str | Path) -> OptiOdomRun:
    """Read one ``<experiment>_run-NN.csv``; ``ValueError`` naming the file and line if bad."""
    path = Path(path)
    rows: list[list[float]] = []
    for number, line in text_lines(path):
        fields = line.strip().split(",")
        if fields == [""]:
            continue
        row = number_row(path, number, fields, 6, "an OptiOdom")
        if rows and row[0] <= rows[-1][0]:
            raise ValueError(f"{path}:{number}: time {row[0]} does not increase")
        if row[4] != round(row[4]) or row[5] != round(row[5]):
            raise ValueError(f"{path}:{number}: ticks must be whole counts")
        rows.append(row)
    if len(rows) < 2:
        raise ValueError(f"{path}: a run needs at least 2 rows, got {len(rows)}")
    table = np.array(rows)
    ticks = table[:, [5, 4]].astype(np.int64)  # the file has right, then left
    return OptiOdomRun(path, table[:, 0], table[:, 1:4], ticks)
