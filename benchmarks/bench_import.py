"""``import diffdrive`` against ``import numpy`` alone: wall time of fresh Python processes
that import one or the other, taken alternately (a slow spell falls on both), medians of
``--runs`` each. Target (issue 40): at most 0.03 s more than NumPy alone.

    python benchmarks/bench_import.py [--runs 21]
"""

from __future__ import annotations

import argparse
import platform
import statistics
import subprocess
import sys
import time

TARGET = 0.03  # s over numpy alone


def wall(code: str) -> float:
    start = time.perf_counter()
    subprocess.run([sys.executable, "-c", code], check=True)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=21)
    args = parser.parse_args()
    print(f"{platform.processor() or platform.machine()}, Python {platform.python_version()}")
    times: dict[str, list[float]] = {"pass": [], "import numpy": [], "import diffdrive": []}
    for _ in range(args.runs):
        for code in times:
            times[code].append(wall(code))
    medians = {code: statistics.median(taken) for code, taken in times.items()}
    for code, median in medians.items():
        print(f"  python -c {code!r}: {median:.3f} s (median of {args.runs})")
    extra = medians["import diffdrive"] - medians["import numpy"]
    print(f"  diffdrive over numpy: {extra:.3f} s (target <= {TARGET} s)")


if __name__ == "__main__":
    main()
