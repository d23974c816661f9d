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


def per_call(loops, repeats):
    """Median seconds per call of each of ``loops`` (name: a loop that returns how many calls
    it made), taken in rounds that run every loop once, after a round that is not timed: a
    slow spell of the machine falls on all of them alike, not on one."""
    times = {name: [] for name in loops}
    for round in range(repeats + 1):
        for name, loop in loops.items():
            start = time.perf_counter()
            calls = loop()
            if round:
                times[name].append((time.perf_counter() - start) / calls)
    return {name: statistics.median(taken) for name, taken in times.items()}
