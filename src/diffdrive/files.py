"""Files: tables of numbers and robot files in; trajectories out (CSV, JSON lines, TUM).

Input tables are CSV with a header row of column names. ``read_table`` checks every cell and
names the file, the line and the column of the first one that is wrong; a file that cannot
be read whole is refused whole.

Trajectories go out as CSV (``t,x,y,theta``), JSON lines (one ``{"t", "x", "y", "theta"}``
object a line), or the TUM format (``t x y z qx qy qz qw``, the heading as a rotation about z),
which the evo odometry-evaluation tool reads. Every writer writes a temporary file beside the
target and renames it, so a failure leaves no partial file.
"""

from __future__ import annotations

import contextlib
import csv
import json
import math
import os
import tempfile
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Literal, TextIO

import numpy as np

__all__ = [
    "FORMATS",
    "ROBOT_KEYS",
    "TableError",
    "atomic_output",
    "atomic_write",
    "read_header",
    "read_robot",
    "read_run",
    "read_table",
    "read_trajectory",
    "write_robot",
    "write_trajectory",
]

# What a robot file may set: the DiffDrive's arguments, and the encoders' resolution.
ROBOT_KEYS = (
    "wheel_radius",
    "left_wheel_radius",
    "right_wheel_radius",
    "track_width",
    "axle_offset",
    "ticks_per_revolution",
)

Format = Literal["csv", "jsonl", "tum"]
FORMATS: tuple[Format, ...] = ("csv", "jsonl", "tum")


class TableError(ValueError):
    """A bad input file; the message names the file, and the line and column when known."""


def read_header(path: str | Path) -> list[str]:
    """The column names in the first row of a CSV file."""
    path = Path(path)
    try:
        with path.open(newline="") as handle:
            header = next(csv.reader(handle), None)
    except OSError as exc:
        raise TableError(f"{path}: cannot read: {exc.strerror}") from None
    if header is None:
        raise TableError(f"{path}: the file is empty; expected a header row")
    return [name.strip() for name in header]


def read_table(
    path: str | Path,
    required: Sequence[str],
    optional: Sequence[str] = (),
    increasing: str | None = "t",
    integers: Sequence[str] = (),
) -> dict[str, np.ndarray]:
    """The columns ``required`` (and those of ``optional`` present) of a CSV file, as floats.

    Every value must be a finite number, whole in the columns ``integers``; the column
    ``increasing`` must increase strictly. Raises ``TableError`` naming the file, line and
    column of the first bad cell.
    """
    path = Path(path)
    try:
        handle = path.open(newline="")
    except OSError as exc:
        raise TableError(f"{path}: cannot read: {exc.strerror}") from None
    with handle:
        rows = csv.reader(handle)
        header = next(rows, None)
        if header is None:
            expected = ", ".join(required)
            raise TableError(f"{path}: the file is empty; expected a header with {expected}")
        names = [name.strip() for name in header]
        missing = [name for name in required if name not in names]
        if missing:
            raise TableError(
                f"{path}:1: missing column {missing[0]!r} (the header has: {', '.join(names)})"
            )
        wanted = [*required, *(name for name in optional if name in names)]
        index = {name: names.index(name) for name in wanted}
        values: dict[str, list[float]] = {name: [] for name in wanted}
        for line, row in enumerate(rows, start=2):
            if not row or all(not cell.strip() for cell in row):
                continue
            for name, column in index.items():
                cell = row[column].strip() if column < len(row) else ""
                try:
                    number = float(cell)
                except ValueError:
                    raise TableError(
                        f"{path}:{line}: column {name!r}: not a number: {cell!r}"
                    ) from None
                if not math.isfinite(number):
                    raise TableError(f"{path}:{line}: column {name!r}: not finite: {cell!r}")
                if name in integers and number != round(number):
                    raise TableError(f"{path}:{line}: column {name!r}: not a whole count: {cell!r}")
                column_values = values[name]
                if name == increasing and column_values and number <= column_values[-1]:
                    raise TableError(
                        f"{path}:{line}: column {name!r}: {cell} does not increase after "
                        f"{column_values[-1]!r}"
                    )
                column_values.append(number)
    if not values[required[0]]:
        raise TableError(f"{path}: no rows of data after the header")
    return {name: np.array(column) for name, column in values.items()}


def read_trajectory(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """``(times (T+1,), poses (T+1, 3))`` from a CSV with columns ``t, x, y, theta``."""
    table = read_table(path, ["t", "x", "y", "theta"])
    poses = np.column_stack([table["x"], table["y"], table["theta"]])
    if len(poses) < 2:
        raise TableError(f"{path}: a trajectory needs at least 2 rows")
    return table["t"], poses


def read_robot(path: str | Path) -> dict[str, float]:
    """The settings of a robot file (TOML): ``ROBOT_KEYS``, lengths in m.

    Returns them as a dict; ``TableError`` names the file (and the line, for a syntax error)
    of anything wrong.
    """
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        import tomli as tomllib
    path = Path(path)
    try:
        with path.open("rb") as handle:
            settings = tomllib.load(handle)
    except OSError as exc:
        raise TableError(f"{path}: cannot read: {exc.strerror}") from None
    except tomllib.TOMLDecodeError as exc:
        raise TableError(f"{path}: not valid TOML: {exc}") from None
    unknown = sorted(set(settings) - set(ROBOT_KEYS))
    if unknown:
        raise TableError(
            f"{path}: unknown setting {unknown[0]!r}; a robot file may set {', '.join(ROBOT_KEYS)}"
        )
    for key, value in settings.items():
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise TableError(f"{path}: {key} must be a number, got {value!r}")
    return {key: float(value) for key, value in settings.items()}


@contextlib.contextmanager
def atomic_output(path: str | Path) -> Iterator[Path]:
    """A temporary path beside ``path`` (same suffix), renamed to ``path`` once written.

    On any failure the temporary file goes and ``path`` is left as it was.
    """
    path = Path(path)
    handle, temporary = tempfile.mkstemp(
        dir=path.parent or ".", prefix=f".{path.stem}.", suffix=path.suffix
    )
    os.close(handle)
    try:
        yield Path(temporary)
        # mkstemp makes the file private (0600); give it the mode a plain open would.
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(temporary, 0o666 & ~umask)
        os.replace(temporary, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(temporary)
        raise


@contextlib.contextmanager
def atomic_write(path: str | Path) -> Iterator[TextIO]:
    """A text file to write that appears at ``path`` only once it is complete."""
    with atomic_output(path) as temporary, temporary.open("w", newline="") as stream:
        yield stream


def write_robot(path: str | Path, settings: dict[str, float], comment: str = "") -> None:
    """Write a robot file (TOML) that ``read_robot`` reads back: ``ROBOT_KEYS`` only."""
    unknown = sorted(set(settings) - set(ROBOT_KEYS))
    if unknown:
        raise ValueError(f"not a robot setting: {unknown[0]!r}")
    with atomic_write(path) as stream:
        stream.writelines(f"# {line}\n" for line in comment.splitlines())
        stream.writelines(f"{key} = {float(value)!r}\n" for key, value in settings.items())


def read_run(path: str | Path, ticks_per_revolution: float | None) -> tuple:
    """A run with ground truth: ``(times (T+1,), increments (T, 2) rad, truth (T+1, 3))``.

    Either the OptiOdom format (no header; see ``diffdrive.datasets``) or a CSV with columns
    ``t``, ``x``, ``y``, ``theta`` and ``left_ticks, right_ticks`` (with
    ``ticks_per_revolution``) or ``left_angle, right_angle`` (rad).
    """
    header = read_header(path)
    if all(_is_number(name) for name in header):
        from diffdrive.datasets import read_optiodom_run

        run = read_optiodom_run(path)
        return run.times, np.diff(run.wheel_angles(), axis=0), run.ground_truth
    ticks = "left_ticks" in header
    wheels = ("left_ticks", "right_ticks") if ticks else ("left_angle", "right_angle")
    table = read_table(path, ["t", *wheels, "x", "y", "theta"], integers=wheels if ticks else ())
    angles = np.column_stack([table[wheels[0]], table[wheels[1]]])
    if ticks:
        if ticks_per_revolution is None:
            raise TableError(f"{path}: ticks need ticks_per_revolution")
        angles = angles * (2 * math.pi / ticks_per_revolution)
    truth = np.column_stack([table["x"], table["y"], table["theta"]])
    return table["t"], np.diff(angles, axis=0), truth


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def write_trajectory(
    path: str | Path, times: np.ndarray, poses: np.ndarray, format: Format = "csv"
) -> None:
    """Write poses ``(T+1, 3)`` at ``times`` ``(T+1,)`` to ``path`` as ``format``."""
    if format not in FORMATS:
        raise ValueError(f"format must be one of {', '.join(FORMATS)}, got {format!r}")
    rows = np.column_stack([times, poses]).tolist()
    with atomic_write(path) as stream:
        if format == "csv":
            stream.write("t,x,y,theta\n")
            stream.writelines(f"{t!r},{x!r},{y!r},{theta!r}\n" for t, x, y, theta in rows)
        elif format == "jsonl":
            stream.writelines(
                json.dumps({"t": t, "x": x, "y": y, "theta": theta}) + "\n"
                for t, x, y, theta in rows
            )
        else:
            stream.write("# t x y z qx qy qz qw\n")
            stream.writelines(
                f"{t!r} {x!r} {y!r} 0.0 0.0 0.0 {math.sin(theta / 2)!r} {math.cos(theta / 2)!r}\n"
                for t, x, y, theta in rows
            )
