"""Tables of numbers: the text files that loggers and spreadsheets write.

Input tables are text with a header row of column names, as spreadsheets and loggers write
them: UTF-8 (a byte-order mark, as Excel writes, is read), separated by commas, semicolons, tabs
or runs of spaces (sniffed from the header), with ``#`` comment lines skipped. In a file
separated by semicolons or tabs a decimal comma (``0,5``) is read as a decimal point.
``read_table`` checks every cell and names the file, the line and the column of the first one
that is wrong; a file that cannot be read whole is refused whole.

Time columns are in seconds unless told otherwise (``time_unit``: ``s``, ``ms``, ``us``, ``ns``).
A time column that plainly is not in seconds (rows 10 s or more apart, or stamps since 1970
in ms, us or ns) is refused with the likely unit named, rather than read as seconds.
"""

from __future__ import annotations

import codecs
import csv
import io
import math
import warnings
from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np

from diffdrive.errors import TableError

__all__ = [
    "TIME_UNITS",
    "Table",
    "TableError",
    "check_time_unit",
    "is_number",
    "number_row",
    "read_header",
    "read_table",
    "refuse_a_slow_wheel_log",
    "text_lines",
    "times_in_seconds",
]

TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
"""Seconds per unit of a time column, by the unit's name."""
# Stamps since 1970 in seconds stay below 1e11 until the year 5138; larger ones are finer units.
_EPOCH_LIMIT = 1e11
# Rows this far apart (s, the median) are no log of a moving robot: a log in ms at 100 Hz
# or slower steps by 10 or more. Hand-written histories that hold each row this long need
# --time-unit s.
_LONGEST_STEP = 10.0
# A wheel log of this many rows or more, a second or more apart, is no robot's either: its
# wheels are logged at 10 Hz or faster. Rows 1 to 9 apart are a log in ms at 100 Hz to 1 kHz
# (a 200 Hz log in ms simulated 530 turns over "9995 s" as seconds).
_SLOWEST_WHEEL_STEP = 1.0
_MANY_ROWS = 100


class Table(dict):
    """Columns of a table by name, as arrays; ``lines`` holds each row's line in the file."""

    def __init__(self, path: Path, columns: dict[str, np.ndarray], lines: np.ndarray) -> None:
        super().__init__(columns)
        self.path = path
        self.lines = lines


def text_lines(path: str | Path) -> Iterator[tuple[int, str]]:
    """``(line number, text)`` of each line of a UTF-8 text file (a byte-order mark is skipped).

    ``TableError`` names the file and the line of bytes that are not UTF-8.
    """
    path = Path(path)
    try:
        handle = path.open("rb")
    except OSError as exc:
        raise TableError(f"{path}: cannot read: {exc.strerror}") from None
    decoder = codecs.getincrementaldecoder("utf-8")()
    with handle:
        for number, raw in enumerate(_physical_lines(handle), start=1):
            if number == 1 and raw.startswith(codecs.BOM_UTF8):
                raw = raw[len(codecs.BOM_UTF8) :]
            try:
                text = decoder.decode(raw)
            except UnicodeDecodeError as exc:
                hint = " (UTF-16?)" if raw[:2] in (codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE) else ""
                raise TableError(
                    f"{path}:{number}: not UTF-8 text{hint}: byte {raw[exc.start]:#04x} at "
                    f"column {exc.start + 1}; save the file as UTF-8"
                ) from None
            if "\0" in text:
                raise TableError(f"{path}:{number}: a NUL byte: this is not a text file")
            yield number, text.rstrip("\r\n")


def _physical_lines(handle) -> Iterator[bytes]:
    """The lines of a binary file ended by LF, CR LF or a lone CR (old Macs, some loggers)."""
    for raw in handle:
        pieces = raw.split(b"\r")
        if len(pieces) > 1 and pieces[-1] in (b"\n", b""):
            pieces.pop()  # CR LF, or a CR that ends the file
        yield from pieces


def is_number(text: str) -> bool:
    """Whether ``text`` reads as a float (a header of numbers is no header)."""
    try:
        float(text)
    except ValueError:
        return False
    return True


def number_row(path: Path, number: int, fields: list[str], size: int, what: str) -> list[float]:
    """``size`` finite numbers from the ``fields`` of line ``number`` of ``path`` (a ``what``
    line), or ``TableError`` naming the file and line."""
    if len(fields) != size:
        raise TableError(f"{path}:{number}: {what} line has {size} fields, got {len(fields)}")
    line = " ".join(fields)
    try:
        row = [float(field) for field in fields]
    except ValueError:
        raise TableError(f"{path}:{number}: not a number in {line[:60]!r}") from None
    if not all(math.isfinite(value) for value in row):
        raise TableError(f"{path}:{number}: not finite: {line[:60]!r}")
    return row


def _splitter(header: str):
    """A function that splits a line into cells, chosen by the separator the header uses."""
    counts = {sep: header.count(sep) for sep in (",", ";", "\t")}
    separator = max(counts, key=lambda sep: counts[sep])
    if counts[separator] == 0:
        return str.split
    decimal_comma = separator != ","
    csv.field_size_limit(2**31 - 1)  # a cell of any size is an error with a line, not a crash

    def split(line: str) -> list[str]:
        cells = next(csv.reader([line], delimiter=separator), [])
        return [cell.replace(",", ".") for cell in cells] if decimal_comma else cells

    return split


def _rows(path: Path) -> Iterator[tuple[int, list[str]]]:
    """``(line number, cells)`` of each non-blank, non-comment line; the header first."""
    split = None
    for number, text in text_lines(path):
        if not text.strip() or text.lstrip().startswith("#"):
            continue
        if split is None:
            split = _splitter(text)
        yield number, [cell.strip() for cell in split(text)]


def read_header(path: str | Path) -> list[str]:
    """The column names in the first row of a table."""
    path = Path(path)
    first = next(_rows(path), None)
    if first is None:
        raise TableError(f"{path}: the file is empty; expected a header row")
    return first[1]


def check_time_unit(unit: str | None) -> str | None:
    """``unit`` if it is one of ``TIME_UNITS`` (or None: seconds, checked)."""
    if unit is not None and unit not in TIME_UNITS:
        raise ValueError(f"time unit must be one of {', '.join(TIME_UNITS)}, got {unit!r}")
    return unit


def _likely_unit(times: np.ndarray) -> str | None:
    """The unit a time column in seconds is plainly not in, or None when seconds may be right."""
    start = abs(float(times[0]))
    step = float(np.median(np.diff(times))) if len(times) > 1 else 0.0
    if start >= _EPOCH_LIMIT:  # stamps since 1970: 1.7e12 ms, 1.7e15 us, 1.7e18 ns
        return min(("ms", "us", "ns"), key=lambda u: abs(math.log10(start * TIME_UNITS[u] / 1.7e9)))
    if step >= _LONGEST_STEP:  # the unit that makes the log's rate nearest 50 Hz
        return min(("ms", "us", "ns"), key=lambda u: abs(math.log10(step * TIME_UNITS[u] * 50)))
    return None


def times_in_seconds(table: dict, name: str, unit: str | None, path: Path) -> None:
    """Scale ``table[name]`` to seconds; refuse a column that is plainly in another unit."""
    times = table[name]
    if unit is None:
        likely = _likely_unit(times)
        if likely is not None:
            step = float(np.median(np.diff(times))) if len(times) > 1 else 0.0
            rate = f", a {1 / (step * TIME_UNITS[likely]):.3g} Hz log in {likely}" if step else ""
            raise TableError(
                f"{path}: column {name!r} is not in seconds: it starts at {times[0]:.6g} with "
                f"rows {step:.3g} apart{rate}; give the time unit (--time-unit {likely}), or "
                "--time-unit s to read it as seconds all the same"
            )
        return
    if unit != "s":
        table[name] = times * TIME_UNITS[unit]


def refuse_a_slow_wheel_log(times: np.ndarray, name: str, path: Path) -> None:
    """Refuse a wheel log's time column read as seconds whose rows are ``_SLOWEST_WHEEL_STEP``
    or more apart over ``_MANY_ROWS`` rows or more: no robot logs its wheels that slowly."""
    if len(times) < _MANY_ROWS:
        return
    step = float(np.median(np.diff(times)))
    if step < _SLOWEST_WHEEL_STEP:
        return
    raise TableError(
        f"{path}: column {name!r} is not in seconds: {len(times)} rows {step:.3g} apart, "
        f"{times[-1] - times[0]:.6g} in all, a wheel log at {1 / step:.3g} Hz, slower than any "
        f"robot logs its wheels; a {1 / (step * TIME_UNITS['ms']):.3g} Hz log in ms? Give the "
        "time unit (--time-unit ms), or --time-unit s to read it as seconds all the same"
    )


def _whole(cell: str) -> int:
    """A cell of whole counts as an exact int (no rounding through float for 64-bit values)."""
    try:
        return int(cell)
    except ValueError:
        number = float(cell)  # "1000.0", "1e3": whole, and exact below 2^53
        if not math.isfinite(number):
            raise
        if number != math.floor(number) or abs(number) >= 2.0**53:
            raise ValueError("not whole") from None
        return int(number)


def _integer_array(values: list[int], name: str, path: Path) -> np.ndarray:
    if min(values) >= -(2**63) and max(values) < 2**63:
        return np.array(values, dtype=np.int64)
    if min(values) >= 0 and max(values) < 2**64:
        return np.array(values, dtype=np.uint64)
    raise TableError(f"{path}: column {name!r}: counts beyond 64 bits")


def read_table(
    path: str | Path,
    required: Sequence[str],
    optional: Sequence[str] = (),
    increasing: str | None = "t",
    integers: Sequence[str] = (),
    time_unit: str | None = None,
) -> Table:
    """The columns ``required`` (and those of ``optional`` present) of a table.

    Every value must be a finite number; the columns ``integers`` hold whole counts, read
    exactly as int64 (uint64 for unsigned 64-bit readings); the others are float64. The column
    ``increasing`` must increase strictly and is a time in ``time_unit`` (None: seconds,
    refused when plainly not), returned in seconds. Raises ``TableError`` naming the file, line
    and column of the first bad cell.
    """
    path = Path(path)
    check_time_unit(time_unit)
    rows = _rows(path)
    try:
        _, names = next(rows)
    except StopIteration:
        expected = ", ".join(required)
        raise TableError(f"{path}: the file is empty; expected a header with {expected}") from None
    missing = [name for name in required if name not in names]
    if missing:
        raise TableError(
            f"{path}:1: missing column {missing[0]!r} (the header has: {', '.join(names)})"
        )
    wanted = [*required, *(name for name in optional if name in names)]
    index = {name: names.index(name) for name in wanted}
    fast = _read_plain_csv(path, index, integers, increasing)
    if fast is not None:
        table, fast_lines = fast
        if increasing is not None and increasing in table:
            times_in_seconds(table, increasing, time_unit, path)
        return Table(path, table, fast_lines)
    values: dict[str, list] = {name: [] for name in wanted}
    lines: list[int] = []
    try:
        for line, row in rows:
            for name, column in index.items():
                values[name].append(_cell(row, column, name, name in integers, path, line))
                column_values = values[name]
                if (
                    name == increasing
                    and len(column_values) > 1
                    and not column_values[-1] > column_values[-2]
                ):
                    raise TableError(
                        f"{path}:{line}: column {name!r}: {row[column]} does not increase "
                        f"after {column_values[-2]!r}"
                    )
            lines.append(line)
    except csv.Error as exc:
        raise TableError(f"{path}: not a table of numbers: {exc}") from None
    if not lines:
        raise TableError(f"{path}: no rows of data after the header")
    table = {
        name: _integer_array(column, name, path) if name in integers else np.array(column)
        for name, column in values.items()
    }
    if increasing is not None and increasing in table:
        times_in_seconds(table, increasing, time_unit, path)
    return Table(path, table, np.array(lines))


def _read_plain_csv(path: Path, index: dict[str, int], integers, increasing):
    """The columns of a plain CSV file (UTF-8, a header on line 1, commas, no comment or blank
    lines, every value good) by NumPy's parser, with the line of each row; None when the file
    is anything else, so that the cell-by-cell reader reads it or names what is wrong."""
    try:
        text = path.read_bytes().decode("utf-8")
    except (OSError, UnicodeDecodeError):
        return None
    header, _, body = text.partition("\n")
    if "," not in header or "#" in text or ";" in header or "\t" in header or "\r" in text:
        return None
    dtype = [(name, np.int64 if name in integers else np.float64) for name in index]
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # an empty body, say: let the other reader say so
            rows = np.loadtxt(
                io.StringIO(body), delimiter=",", usecols=list(index.values()), dtype=dtype, ndmin=1
            )
    except (ValueError, OverflowError, Warning):
        return None
    lines = body.count("\n") + (0 if body.endswith("\n") or not body else 1)
    if len(rows) == 0 or len(rows) != lines:  # blank lines were skipped: count them instead
        return None
    table = {name: np.ascontiguousarray(rows[name]) for name in index}
    floats = [table[name] for name in index if name not in integers]
    if not all(np.isfinite(column).all() for column in floats):
        return None
    if increasing in table and not np.all(np.diff(table[increasing]) > 0):
        return None
    return table, np.arange(2, len(rows) + 2)


def _cell(row: list[str], column: int, name: str, whole: bool, path: Path, line: int):
    cell = row[column] if column < len(row) else ""
    shown = cell if len(cell) <= 40 else cell[:37] + "..."
    try:
        return _whole(cell) if whole else _finite(cell)
    except ValueError:
        pass
    try:
        number = float(cell)
    except ValueError:
        raise TableError(f"{path}:{line}: column {name!r}: not a number: {shown!r}") from None
    if not math.isfinite(number):
        raise TableError(f"{path}:{line}: column {name!r}: not finite: {shown!r}")
    raise TableError(f"{path}:{line}: column {name!r}: not a whole count: {shown!r}")


def _finite(cell: str) -> float:
    number = float(cell)
    if not math.isfinite(number):
        raise ValueError(cell)
    return number
