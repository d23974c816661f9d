"""``estimate_trajectory`` on a long log: the C core's whole-log pass against its Python twin
(the core every whole log ran on before), side by side in one run.

The log: a 0.1 m / 0.5 m drive at 100 Hz along a winding path, wheel noise ``k`` = 1e-4 m, a
gyro with a bias of 2e-3 rad/s and white rate noise, heading ``"fused"`` (the bias a state,
the slip test and its episodes on, the wheels' noise identified against the gyro as with no
setting given), and, in a second variant, a position fix every second.
Timed: the filter (``smooth=False``) and the filter with the smoother, in microseconds per
wheel interval, medians of ``--repeats`` runs; the C core on ``--intervals`` (10^6: 2.8 hours
of driving), the Python twin on ``--twin-intervals``. Targets (issue 40): on 10^6 intervals
with a gyro, the filter at most 3 us an interval, the filter and smoother at most 6 us.

    python benchmarks/bench_smoother.py [--intervals 1000000] [--twin-intervals 20000]
"""

from __future__ import annotations

import argparse
import platform

import numpy as np

import diffdrive as dd
from diffdrive.estimation import (
    EstimatorSettings,
    Gyro,
    Window,
    estimate_trajectory,
    fusion,
    measurements_of,
)
from diffdrive.estimation import smoother as whole
from diffdrive.estimation.episodes import EDGE_COST, EPISODE_PENALTY, LONGEST, partition
from diffdrive.estimation.wheel_turns import identify_wheel_turns
from timing import median_time  # benchmarks/timing.py

ROBOT = dd.DiffDrive(wheel_radius=0.1, track_width=0.5)
RATE = 100.0
TARGETS = {False: 3.0, True: 6.0}  # us per interval: the filter, and with the smoother


def log(intervals: int, fixes: bool, seed: int = 0):
    """times, increments, the gyro and the measurements of a synthetic log."""
    rng = np.random.default_rng(seed)
    times = np.arange(intervals + 1) / RATE
    t = times[:-1]
    wheels = np.column_stack([8 + 3 * np.cos(t / 2.3), 8 + 3 * np.sin(t / 3.1)])
    truth = dd.simulate(ROBOT, wheels, times=times).poses
    travel = wheels / RATE
    noise = np.sqrt(1e-4 * np.abs(0.1 * travel)) / 0.1
    increments = travel + rng.normal(size=travel.shape) * noise
    rate = np.gradient(np.unwrap(truth[:, 2]), times) + 2e-3 + rng.normal(size=len(times)) * 0.02
    measured = []
    if fixes:
        every = int(RATE)
        seen = truth[::every, :2] + rng.normal(size=(len(times[::every]), 2)) * 0.5
        measured = measurements_of("position", times[::every], seen, 0.5)
    return times, increments, Gyro(times, rate), measured


def per_interval(times, increments, gyro, measured, smooth, repeats, settings=None) -> float:
    def run():
        return estimate_trajectory(
            ROBOT, times, increments, gyro=gyro, measurements=measured, smooth=smooth,
            settings=settings,
        )  # fmt: skip

    return median_time(run, repeats) / (len(times) - 1) * 1e6


def parts(times, increments, gyro, repeats) -> dict[str, float]:
    """us per interval of the pieces: the C pass alone, forward and with the smoother, the
    episodes' partition, and what a whole log reads from itself before the pass: the gyro's
    interpolation and the wheels' noise against the gyro."""
    whole_log = EstimatorSettings(window=Window(np.inf, 0.0))
    estimator = fusion.PoseEstimator(ROBOT, whole_log, initial_time=0.0)
    n = len(times) - 1
    turned, spread = np.diff(gyro.angles(times)), gyro.interpolation_variances(times)
    log_ = whole._Log(times, increments, turned, spread, np.zeros(n, bool), whole._packed([]))
    rng = np.random.default_rng(1)
    scaled, directions = rng.normal(size=n), rng.normal(size=(n, 2))
    work = {
        "the C pass, forward": lambda: whole._run(estimator, log_, False, None),
        "the C pass, forward and back": lambda: whole._run(estimator, log_, True, None),
        "the episodes' partition": lambda: partition(
            scaled, directions, EPISODE_PENALTY, EDGE_COST, LONGEST
        ),
        "the gyro's interpolation": lambda: gyro.interpolation_variances(times),
        "the wheels' noise against the gyro": lambda: identify_wheel_turns(
            ROBOT, times, increments, turned, 0.02, spread
        ),
    }
    return {name: median_time(run, repeats) / n * 1e6 for name, run in work.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--intervals", type=int, default=1_000_000)
    parser.add_argument("--twin-intervals", type=int, default=20_000)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    print(f"{platform.processor() or platform.machine()}, Python {platform.python_version()}")
    if not fusion.COMPILED:
        raise SystemExit("the C core was not built: nothing to compare")
    print(f"us per wheel interval, medians of {args.repeats} runs\n")
    print("| log | pass | C core | Python twin | twin / C | target |")
    print("|---|---|---|---|---|---|")
    for fixes in (False, True):
        name = "gyro, fixes at 1 Hz" if fixes else "gyro"
        big = log(args.intervals, fixes)
        small = log(args.twin_intervals, fixes)
        for smooth in (False, True):
            c = per_interval(*big, smooth, args.repeats)
            whole.PoseEstimator = fusion._PythonPoseEstimator  # the twin, for this timing only
            try:
                twin = per_interval(*small, smooth, args.repeats)
            finally:
                whole.PoseEstimator = fusion.PoseEstimator
            passes = "filter and smoother" if smooth else "filter"
            print(
                f"| {name} | {passes} | {c:.2f} | {twin:.0f} | {twin / c:.0f} | "
                f"<= {TARGETS[smooth]:.0f} |"
            )
    big = log(args.intervals, False)
    given = EstimatorSettings(wheel_noise=1e-4)
    print("\nthe wheels' noise given (k = 1e-4 m) against identified, C core, side by side:")
    for smooth in (False, True):
        identified = per_interval(*big, smooth, args.repeats)
        held = per_interval(*big, smooth, args.repeats, given)
        passes = "filter and smoother" if smooth else "filter"
        print(
            f"  {passes}: {held:.2f} given, {identified:.2f} identified ({identified / held:.2f}x)"
        )
    print("\nits pieces, gyro log, us per interval:")
    for piece, cost in parts(*log(args.intervals, False)[:3], args.repeats).items():
        print(f"  {piece}: {cost:.2f}")


if __name__ == "__main__":
    main()
