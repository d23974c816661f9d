"""What a script of ``examples/`` printed when the guides' figures were taken (its record,
``examples/records/NAME.txt``, written by ``benchmarks/record.py``), held against a run of
it in the tests: the same lines, each number to its last printed digit or 0.5 %, whichever
is wider (a different BLAS may move the last digit)."""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
NUMBER = re.compile(r"[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?")
# A record's first line: the command (the script by its folder, and its arguments), the date
# (UTC) and the machine, as benchmarks/record.py writes it.
HEADER = (
    r"# python (examples|benchmarks)/\w+\.py[^:]*: 20\d\d-\d\d-\d\d \d\d:\d\d UTC, .+ cores, "
    r"Python 3\.\d+\.\d+, NumPy \d+\.\d+\.\d+"
)


def record(folder: str, name: str) -> list[str]:
    """The lines ``folder``/``name``.py printed, as its record keeps them (the header
    line, which says when and where, left out)."""
    lines = (ROOT / folder / "records" / f"{name}.txt").read_text().splitlines()
    return [line for line in lines[1:] if line.strip()]


def _close(printed: str, recorded: str) -> bool:
    value, expected = float(printed), float(recorded)
    digits = recorded.split("e")[0]
    last = 10.0 ** -len(digits.split(".")[1]) if "." in digits else 1.0
    if "e" in recorded:
        last *= 10.0 ** int(recorded.split("e")[1])
    return abs(value - expected) <= max(last, 0.005 * abs(expected))


def _same(printed: str, recorded: str) -> bool:
    words, expected = NUMBER.split(printed), NUMBER.split(recorded)
    numbers, figures = NUMBER.findall(printed), NUMBER.findall(recorded)
    return (
        [" ".join(word.split()) for word in words] == [" ".join(word.split()) for word in expected]
        and len(numbers) == len(figures)
        and all(_close(a, b) for a, b in zip(numbers, figures, strict=True))
    )


def assert_as_recorded(
    name: str, printed: str, only: Callable[[str], bool] | None = None, folder: str = "examples"
) -> None:
    """Each line ``name`` printed (those ``only`` keeps: a run on part of the data) is a line
    of its record; without ``only``, the run printed every line of the record as well. A
    ``figure: PATH`` names where it drew, which the test chose: it is left out."""
    kept = only or (lambda line: True)

    def compared(lines: list[str]) -> list[str]:
        lines = [re.sub(r"\s*figure: \S*", "", line).strip() for line in lines]
        return [line for line in lines if line and kept(line)]

    lines, recorded = compared(printed.splitlines()), compared(record(folder, name))
    assert lines, f"{name} printed none of the lines its record keeps"
    unmatched = [line for line in lines if not any(_same(line, row) for row in recorded)]
    assert unmatched == [], f"{name} printed lines its record does not keep: {unmatched}"
    if only is None:
        missing = [row for row in recorded if not any(_same(line, row) for line in lines)]
        assert missing == [], f"{name} no longer prints these lines of its record: {missing}"
