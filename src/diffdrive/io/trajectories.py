"""Trajectory files: ``t, x, y, theta`` as CSV, JSON lines or TUM, for one robot or many.

- CSV: a header ``t,x,y,theta`` (any table ``diffdrive.io.tables`` reads), optionally a ``robot``
  column first for several robots, and further columns (twist, covariance) after.
- JSON lines: one object a line with the keys ``t``, ``x``, ``y``, ``theta`` (``robot``, and
  any further keys, optional).
- TUM (what evo reads): ``t x y z qx qy qz qw`` a line, ``#`` comments; the heading is the yaw
  of the quaternion. One robot a file: several robots go to ``NAME_0.tum``, ``NAME_1.tum``, ...

Readers find the format from the content: a line of eight numbers is TUM, a line that starts
with ``{`` is JSON lines, anything else is a table. Headings read from TUM are unwrapped (TUM
keeps only the orientation); headings from the others are read as written. ``read_trajectory``
also reads a trajectory topic of a ROS bag or MCAP file (``diffdrive.io.ros``).
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Literal

import numpy as np

from diffdrive.atomic import atomic_output, atomic_write
from diffdrive.io.sniff import is_bag
from diffdrive.io.tables import (
    TableError,
    check_time_unit,
    is_number,
    number_row,
    read_header,
    read_table,
    text_lines,
    times_in_seconds,
)

__all__ = ["FORMATS", "read_trajectory", "trajectory_format", "write_trajectory"]

Format = Literal["csv", "jsonl", "tum"]
FORMATS: tuple[Format, ...] = ("csv", "jsonl", "tum")
"""The trajectory file formats: CSV, JSON lines and TUM."""
_POSE = ("t", "x", "y", "theta")
_ROWS_PER_WRITE = 1 << 16
_BAG_TYPES = (
    "nav_msgs/msg/Odometry",
    "geometry_msgs/msg/PoseWithCovarianceStamped",
    "sensor_msgs/msg/NavSatFix",
)


def trajectory_format(path: str | Path) -> Format:
    """The format of a trajectory file, from its first line that is not blank or a comment."""
    for _, text in text_lines(path):
        line = text.strip()
        if not line or line.startswith("#"):
            continue
        if line.startswith("{"):
            return "jsonl"
        fields = line.split()
        if len(fields) == 8 and all(is_number(field) for field in fields):
            return "tum"
        return "csv"
    raise TableError(f"{path}: the file is empty; expected a trajectory")


def read_trajectory(
    path: str | Path,
    time_unit: str | None = None,
    topic: str | None = None,
    datum: object = None,
) -> tuple[np.ndarray, np.ndarray]:
    """``(times (T+1,), poses (T+1, 3))`` of a trajectory file or of a bag's ``topic``.

    A file may hold ``N`` robots (a ``robot`` column) at the same times: then the poses are
    ``(N, T+1, 3)``. Its times are in ``time_unit`` (None: seconds, refused when plainly
    not; see ``diffdrive.io.tables``), returned in seconds. A bag's topic is
    ``nav_msgs/Odometry``, ``sensor_msgs/NavSatFix`` (local east, north; the heading
    unknown, NaN; at ``datum`` (lat deg, lon deg, altitude m), else at the first fix) or
    ``tf:PARENT:CHILD`` (a transform chain). An OptiOdom run file (no
    header) gives its ground truth. ``TableError`` names the file and line.
    """
    if is_bag(path):
        return _read_bag(path, topic, datum)
    if topic is not None:
        raise TableError(f"{path}: a topic needs a bag; this is a trajectory file")
    path = Path(path)
    check_time_unit(time_unit)
    format = trajectory_format(path)
    if format == "csv" and all(is_number(name) for name in read_header(path)):
        # A table without a header: an OptiOdom run file, whose ground truth is the path.
        from diffdrive.io.optiodom import read_optiodom_run

        run = read_optiodom_run(path, time_unit)
        assert run.truth is not None
        return run.times, run.truth
    if format == "tum":
        table = _read_tum(path)
    elif format == "jsonl":
        table = _read_jsonl(path)
    else:
        table = read_table(path, _POSE, ["robot"], increasing=None)
    robots = table.pop("robot", None)
    times_in_seconds(table, "t", time_unit, path)
    times, poses = _split_robots(path, table, robots)
    if poses.shape[-2] < 2:
        raise TableError(f"{path}: a trajectory needs at least 2 poses")
    bad = np.flatnonzero(np.diff(times) <= 0)
    if bad.size:
        raise TableError(f"{path}: the times do not increase after t = {times[bad[0]]!r}")
    return times, poses


def _read_bag(path: str | Path, topic: str | None, datum) -> tuple[np.ndarray, np.ndarray]:
    from diffdrive.io import ros

    if topic is None:
        usable = [t.name for t in ros.topics(path) if t.msgtype in _BAG_TYPES]
        raise TableError(
            f"{path}: give the topic of a trajectory (--topic or --truth-topic): one of "
            f"{', '.join(usable) or 'none here'}, or tf:PARENT:CHILD"
        )
    if topic.startswith("tf:"):
        frames = topic.split(":")
        if len(frames) != 3:
            raise TableError(f"a transform chain is tf:PARENT:CHILD, got {topic!r}")
        times, poses = ros.read_tf(path, frames[1], frames[2])
    else:
        kind = {t.name: t.msgtype for t in ros.topics(path)}.get(topic)
        if kind == "sensor_msgs/msg/NavSatFix":
            fixes = ros.read_navsatfix(path, topic, datum)
            times = fixes.times
            poses = np.column_stack([fixes.positions, np.full(len(times), np.nan)])
        else:
            odometry = ros.read_odometry(path, topic)  # names the topic if it is not one
            times, poses = odometry.times, odometry.poses
    if len(times) < 2:
        raise TableError(f"{path}: {topic} needs 2 or more poses")
    return times, poses


def _split_robots(path: Path, table: dict, robots) -> tuple[np.ndarray, np.ndarray]:
    poses = np.column_stack([table["x"], table["y"], table["theta"]])
    if robots is None:
        return table["t"], poses
    ids = np.unique(robots)
    counts = [np.count_nonzero(robots == k) for k in ids]
    if len(set(counts)) != 1:
        raise TableError(f"{path}: the robots have different numbers of rows ({counts})")
    order = np.argsort(robots, kind="stable")
    times = table["t"][order].reshape(len(ids), -1)
    if not np.array_equal(times, np.broadcast_to(times[0], times.shape)):
        raise TableError(f"{path}: the robots must share their sample times")
    return times[0], poses[order].reshape(len(ids), -1, 3)


def _read_tum(path: Path) -> dict[str, np.ndarray]:
    rows = _plain_tum(path)
    if rows is None:  # not plain, or a bad value: the careful reader names the line
        rows = _careful_tum(path)
    t, x, y, _, qx, qy, qz, qw = rows.T
    yaw = np.arctan2(2 * (qw * qz + qx * qy), 1 - 2 * (qy**2 + qz**2))
    return {"t": t, "x": x, "y": y, "theta": np.unwrap(yaw)}


def _plain_tum(path: Path) -> np.ndarray | None:
    """The rows ``(N, 8)`` of a plain TUM file (UTF-8, comments only before the first pose,
    every value finite, no zero quaternion) by NumPy's parser, as fast as a CSV file's; None
    when the file is anything else."""
    try:
        text = path.read_bytes().decode("utf-8")
    except (OSError, UnicodeDecodeError):
        return None
    lines = text.split("\n")
    first = 0
    while first < len(lines) and (not lines[first].strip() or lines[first].lstrip()[0] == "#"):
        first += 1
    body = "\n".join(lines[first:])
    if "#" in body or "\r" in body or "," in body:
        return None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # an empty body, say: let the other reader say so
            rows = np.loadtxt(io.StringIO(body), dtype=np.float64, ndmin=2)
    except (ValueError, OverflowError, Warning):
        return None
    if rows.shape[1:] != (8,) or len(rows) == 0 or not np.isfinite(rows).all():
        return None
    if (np.hypot(np.hypot(rows[:, 4], rows[:, 5]), np.hypot(rows[:, 6], rows[:, 7])) == 0).any():
        return None
    return rows


def _careful_tum(path: Path) -> np.ndarray:
    rows = []
    for number, text in text_lines(path):
        line = text.strip()
        if not line or line.startswith("#"):
            continue
        row = number_row(path, number, line.split(), 8, "a TUM")
        if np.hypot(np.hypot(row[4], row[5]), np.hypot(row[6], row[7])) == 0.0:
            raise TableError(f"{path}:{number}: the quaternion is zero")
        rows.append(row)
    if not rows:
        raise TableError(f"{path}: no poses")
    return np.array(rows)


def _read_jsonl(path: Path) -> dict[str, np.ndarray]:
    columns: dict[str, list] = {name: [] for name in _POSE}
    robots: list[int] = []
    for number, text in text_lines(path):
        if not text.strip():
            continue
        try:
            record = json.loads(text)
        except json.JSONDecodeError as exc:
            raise TableError(f"{path}:{number}: not JSON: {exc.msg}") from None
        if not isinstance(record, dict):
            raise TableError(f"{path}:{number}: expected a JSON object a line")
        for name in _POSE:
            value = record.get(name)
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise TableError(f"{path}:{number}: {name!r} must be a number, got {value!r}")
            if not math.isfinite(value):
                raise TableError(f"{path}:{number}: {name!r} is not finite")
            columns[name].append(float(value))
        if "robot" in record:
            robots.append(record["robot"])
    table = {name: np.array(values) for name, values in columns.items()}
    if not columns["t"]:
        raise TableError(f"{path}: no poses")
    if robots:
        if len(robots) != len(columns["t"]):
            raise TableError(f"{path}: 'robot' is on some lines and not on others")
        table["robot"] = np.array(robots)
    return table


def write_trajectory(
    path: str | Path,
    times: np.ndarray,
    poses: np.ndarray,
    format: Format = "csv",
    columns: Mapping[str, np.ndarray] | None = None,
) -> list[Path]:
    """Write poses ``(T+1, 3)`` at ``times`` ``(T+1,)`` to ``path`` as ``format``.

    Poses ``(N, T+1, 3)`` of ``N`` robots (with times ``(T+1,)`` or ``(N, T+1)``) go to one
    CSV or JSON-lines file with a ``robot`` column, or to one TUM file per robot. ``columns``
    adds named ``(T+1,)`` values after ``theta`` (CSV and JSON lines only; NaN is written as
    ``nan`` in CSV and null in JSON). Returns the files written.
    """
    if format not in FORMATS:
        raise ValueError(f"format must be one of {', '.join(FORMATS)}, got {format!r}")
    poses = np.asarray(poses, dtype=float)
    if poses.ndim not in (2, 3) or poses.shape[-1] != 3:
        raise ValueError(f"poses must have shape (T+1, 3) or (N, T+1, 3), got {poses.shape}")
    given_times = np.asarray(times, dtype=float)
    try:
        times = np.broadcast_to(given_times, poses.shape[:-1])
    except ValueError:
        raise ValueError(
            f"times must broadcast to {poses.shape[:-1]} for poses "
            f"{poses.shape}, got {given_times.shape}"
        ) from None
    # What is written must read back: read_trajectory refuses these, so refuse them here.
    if not np.all(np.isfinite(times)):
        raise ValueError("times must be finite")
    if np.any(np.diff(times, axis=-1) <= 0):
        raise ValueError("times must increase strictly (read_trajectory refuses them otherwise)")
    if Path(path).is_dir():
        raise TableError(f"cannot write {path}: it is a folder")
    extra = {name: np.asarray(values, dtype=float) for name, values in (columns or {}).items()}
    for name, given in extra.items():
        if given.shape != poses.shape[:-1]:
            raise ValueError(
                f"column {name!r} must have shape {poses.shape[:-1]}, got {given.shape}"
            )
    if format == "tum":
        if extra:
            raise ValueError(f"TUM files hold poses only; write {', '.join(extra)} as csv or jsonl")
        return _write_tum(Path(path), times, poses)
    robots = poses.shape[0] if poses.ndim == 3 else None
    names = (["robot"] if robots else []) + list(_POSE) + list(extra)
    arrays = [times, poses[..., 0], poses[..., 1], poses[..., 2], *extra.values()]
    if robots:
        arrays.insert(0, np.broadcast_to(np.arange(robots)[:, None], times.shape))
    # + 0.0 turns -0.0 into 0.0: a velocity of -0.0 reads as a sign where there is none.
    columns_flat = [np.ascontiguousarray(column).reshape(-1) + 0.0 for column in arrays]
    _orjson()  # loaded before the file is begun: a SIGTERM inside its import crashes it
    # A block of rows at a time: the text of a whole log would take ten times its numbers.
    with atomic_write(path) as stream:
        if format == "csv":
            stream.write(",".join(names) + "\n")
        for start in range(0, len(columns_flat[0]), _ROWS_PER_WRITE):
            block = [column[start : start + _ROWS_PER_WRITE] for column in columns_flat]
            if robots:
                block[0] = block[0].astype(np.int64)
            if format == "csv":
                text = [_float_texts(column) for column in block]
                stream.write("\n".join(map(",".join, zip(*text, strict=True))) + "\n")
            else:
                rows = zip(*(column.tolist() for column in block), strict=True)
                stream.writelines(json.dumps(_record(names, list(row))) + "\n" for row in rows)
    return [Path(path)]


def _float_texts(values: np.ndarray) -> list[str]:
    """Each value as the shortest text that reads back to the same float (ints as ints).

    orjson, where installed (``pip install 'diffdrive[fast]'``), writes them about twice as
    fast as ``repr``, in the same digits (``1e-5`` where repr writes ``1e-05``).
    """
    array = np.asarray(values)
    orjson = _orjson()
    plain = array.dtype == np.float64 and len(array) and bool(np.isfinite(array).all())
    if orjson is not None and plain:
        text = orjson.dumps(array, option=orjson.OPT_SERIALIZE_NUMPY)
        return text[1:-1].decode("ascii").split(",")
    return list(map(repr, array.tolist()))


def _orjson():
    """orjson, or None where it is not installed. Its extension's import does not survive a
    signal handler raising inside it (a segmentation fault), so the writer loads it before
    it begins a file, not in the middle."""
    try:
        import orjson
    except ModuleNotFoundError:
        return None
    return orjson


def _record(names: list[str], row: list) -> dict:
    """A JSON object of a row: NaN and infinities become null, which JSON has instead."""
    return {k: (v if math.isfinite(v) else None) for k, v in zip(names, row, strict=True)}


def _write_tum(path: Path, times: np.ndarray, poses: np.ndarray) -> list[Path]:
    if poses.ndim == 2:
        targets = [(path, times, poses)]
    else:
        width = len(str(len(poses) - 1))
        targets = [
            (path.with_name(f"{path.stem}_{k:0{width}d}{path.suffix}"), times[k], poses[k])
            for k in range(len(poses))
        ]
    # Every file is written to a temporary first; they are renamed only when all are written.
    with contextlib.ExitStack() as renames:
        for target, t, p in targets:
            temporary = renames.enter_context(atomic_output(target))
            with temporary.open("w", newline="") as stream:
                stream.write("# t x y z qx qy qz qw\n")
                stream.writelines(
                    f"{a!r} {x!r} {y!r} 0.0 0.0 0.0 {math.sin(h / 2)!r} {math.cos(h / 2)!r}\n"
                    for a, x, y, h in np.column_stack([t, p]).tolist()
                )
    return [target for target, _, _ in targets]


# A pose covariance's columns in a table (``diffdrive odometry --covariance``): each name's
# index in the row-major 3x3, the upper triangle.
COVARIANCE_COLUMNS = {
    "cov_xx": 0,
    "cov_xy": 1,
    "cov_xtheta": 2,
    "cov_yy": 4,
    "cov_ytheta": 5,
    "cov_thetatheta": 8,
}


def read_covariances(
    path: str | Path, count: int, time_unit: str | None = None, topic: str | None = None
) -> np.ndarray:
    """The ``count`` pose covariances ``(count, 3, 3)`` of an estimate: a bag's Odometry
    ``topic``, or a table's ``COVARIANCE_COLUMNS``. ``TableError`` names the file and what it
    lacks (the columns, or as many rows as poses)."""
    if is_bag(path):
        from diffdrive.io import ros

        if topic is None:
            raise TableError(f"{path}: which topic's covariances? Give its Odometry topic")
        return ros.read_odometry(path, topic).covariances
    try:
        table = read_table(path, ["t", *COVARIANCE_COLUMNS], time_unit=time_unit)
    except TableError as exc:
        raise TableError(
            f"{exc}: a covariance is needed here (--consistency, --errors), columns "
            f"{', '.join(COVARIANCE_COLUMNS)} (diffdrive odometry --covariance writes them)"
        ) from None
    flat = np.zeros((len(table["t"]), 9))
    for name, index in COVARIANCE_COLUMNS.items():
        flat[:, index] = table[name]
        row, column = divmod(index, 3)
        flat[:, 3 * column + row] = table[name]
    if len(flat) != count:
        raise TableError(f"{path}: {len(flat)} covariances for {count} poses")
    return flat.reshape(-1, 3, 3)
