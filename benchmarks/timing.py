"""The timing every benchmark here shares: the median of repeated wall-clock runs."""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable


def median_time(work: Callable[[], object], repeats: int, warm_up: bool = False) -> float:
    """Median wall time (s) of ``repeats`` calls of ``work``, after one untimed call if
    ``warm_up``."""
    if warm_up:
        work()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        work()
        times.append(time.perf_counter() - start)
    return statistics.median(times)
