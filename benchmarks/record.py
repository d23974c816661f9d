"""Run scripts of ``examples/`` and ``benchmarks/`` and keep what each prints as its record.

The guides quote figures from these scripts; a script's record (``records/NAME.txt`` beside
it) is what it printed when the figures were taken, under a first line that says when, on
which machine and with which command. ``tests/test_docs_figures.py`` finds every figure a
page quotes in the records of the scripts that page names (or in the page's own blocks, the
code, or its ledger), and the example tests hold each example's record against a fresh run::

    python benchmarks/record.py examples/husky_fusion.py benchmarks/bench_odometry.py

Arguments after ``--`` go to every script. A script that fails leaves its record as it was.
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def machine() -> str:
    """The machine in words: processor, cores, Python and NumPy."""
    import numpy

    processor = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as info:
            processor = next(line for line in info if line.startswith("model name"))
            processor = processor.split(":", 1)[1].strip()
    except (OSError, StopIteration):
        pass  # not Linux: platform's word for it
    return (
        f"{processor}, {os.cpu_count()} cores, Python {platform.python_version()}, "
        f"NumPy {numpy.__version__}"
    )


def record(script: Path, arguments: list[str]) -> Path:
    """Run ``script`` with ``arguments`` from the clone's root and write its record."""
    started = datetime.datetime.now(datetime.timezone.utc)
    run = subprocess.run(
        [sys.executable, str(script), *arguments],
        cwd=ROOT,
        capture_output=True,
        text=True,
        # An example's record is held by the tests, which run with one BLAS thread (make
        # test); a benchmark times what the machine gives it.
        env={
            **os.environ,
            **({"OPENBLAS_NUM_THREADS": "1"} if script.parent.name == "examples" else {}),
        },
    )
    if run.returncode:
        raise SystemExit(f"{script} failed (exit {run.returncode}); its record is unchanged:\n"
                         f"{run.stderr}")  # fmt: skip
    from diffdrive.atomic import atomic_write

    path = script.parent / "records" / f"{script.stem}.txt"
    path.parent.mkdir(exist_ok=True)
    command = " ".join(["python", f"{script.parent.name}/{script.name}", *arguments])
    with atomic_write(path) as handle:  # an interrupted write leaves the record it had
        handle.write(f"# {command}: {started:%Y-%m-%d %H:%M} UTC, {machine()}\n{run.stdout}")
    return path


def main(argv: list[str] | None = None) -> None:
    argv = sys.argv[1:] if argv is None else argv
    scripts, rest = (
        (argv[: argv.index("--")], argv[argv.index("--") + 1 :]) if "--" in argv else (argv, [])
    )
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scripts", type=Path, nargs="+")
    for script in parser.parse_args(scripts).scripts:
        script = script.resolve()
        if script.parent.name not in ("examples", "benchmarks") or not script.is_file():
            parser.error(f"{script}: not a script of examples/ or benchmarks/")
        print(record(script, rest))


if __name__ == "__main__":
    main()
