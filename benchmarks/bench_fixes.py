"""Fixes that wander, identified from themselves (``WholeLog(fixes="identified")``)
against the same fixes taken as white noise and against interpolating them, over seeds of a
synthetic drive with a receiver whose offset is a random walk (``tests/test_fixes.py``'s),
side by side in one run.

Per seed: a 300 s mixed drive at 20 Hz, wheels over-reading distance by 3 %, fixes at 2 Hz
wandering 0.3 m/sqrt(s) with 0.2 m of white noise; one fix in four used, the rest left out.
It prints the identified wander's and white noise's errors, how often the distance scale and
the start's heading lie within two of their standard errors, the mean distance to the left-out
fixes of each way (medians over seeds) and what identifying costs (medians of the timed
runs). The Husky's figures are ``examples/husky_fusion.py``'s.

    python benchmarks/bench_fixes.py [--seeds 50]
"""

from __future__ import annotations

import argparse
import math
import platform
import sys
import time
from pathlib import Path

import numpy as np

from diffdrive.estimation import (
    EstimatorSettings,
    WholeLog,
    estimate_trajectory,
    identify_fixes,
    measurements_of,
)

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from test_fixes import ROBOT, drive, miss, predicted, wandering_fixes  # the scenario


def one_seed(seed: int) -> dict:
    times, truth, increments, rng = drive(seed)
    stamps, fixes, offset = wandering_fixes(rng, times, truth, white=0.2)
    wheels = EstimatorSettings("wheels", wheel_noise=1e-4)
    dead = estimate_trajectory(ROBOT, times, increments, settings=wheels, smooth=False)
    fit = identify_fixes(times, dead.poses, stamps, fixes)
    used = np.arange(len(stamps)) % 4 == 0
    left = ~used
    started = time.perf_counter()
    identified = estimate_trajectory(
        ROBOT, times, increments, settings=wheels.replace(whole_log=WholeLog(fixes="identified")),
        measurements=measurements_of("position", stamps[used], fixes[used], 1.0),
    )  # fmt: skip
    cost = time.perf_counter() - started
    spread = math.sqrt(0.2**2 + float(np.var(offset)))  # what a receiver would report
    started = time.perf_counter()
    white = estimate_trajectory(
        ROBOT, times, increments, initial_pose=truth[0],
        measurements=measurements_of("position", stamps[used], fixes[used], spread),
        settings=wheels,
    )  # fmt: skip
    plain = time.perf_counter() - started
    between = np.column_stack(
        [np.interp(stamps[left], stamps[used], fixes[used, i]) for i in (0, 1)]
    )
    heading_sigma = math.sqrt(fit.start_covariance[2, 2])
    return {
        "wander": fit.wander / 0.3 - 1.0,
        "white": fit.white / 0.2 - 1.0,
        "scale inside": abs(fit.fitted_scale - 0.97) < 2 * fit.scale_error,
        "heading inside": abs(fit.start[2] - truth[0, 2]) < 2 * heading_sigma,
        "identified": miss(predicted(identified, times, stamps[left]), fixes[left]),
        "white noise": miss(predicted(white, times, stamps[left]), fixes[left]),
        "interpolated": miss(between, fixes[left]),
        "refused identified": identified.rejected,
        "refused white": white.rejected,
        "cost": cost,
        "plain cost": plain,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=50)
    args = parser.parse_args()
    print(f"{platform.processor() or platform.machine()}, Python {platform.python_version()}")
    runs = [one_seed(seed) for seed in range(args.seeds)]

    def column(name: str) -> np.ndarray:
        return np.array([run[name] for run in runs], dtype=float)

    print(f"{args.seeds} seeds, one fix in four used, 6,000 intervals each\n")
    for name in ("wander", "white"):
        errors = np.abs(column(name))
        print(
            f"{name}: error median {100 * np.median(errors):.1f} %, 90th percentile "
            f"{100 * np.quantile(errors, 0.9):.1f} %"
        )
    for name in ("scale inside", "heading inside"):
        print(f"{name} two standard errors: {100 * column(name).mean():.0f} % of seeds")
    print("\nmean distance to the fixes left out, m (median over seeds):")
    for name in ("identified", "white noise", "interpolated"):
        print(f"  {name}: {np.median(column(name)):.3f}")
    ratio = column("identified") / column("white noise")
    print(f"  identified / white noise: median {np.median(ratio):.2f}, worst {ratio.max():.2f}")
    ratio = column("identified") / column("interpolated")
    print(f"  identified / interpolated: median {np.median(ratio):.2f}, worst {ratio.max():.2f}")
    print(
        f"refused by the gate: identified {int(column('refused identified').sum())}, white "
        f"noise {int(column('refused white').sum())} (all seeds)"
    )
    print(
        f"estimate_trajectory, smoothed: identified {1e3 * np.median(column('cost')):.1f} ms, "
        f"given {1e3 * np.median(column('plain cost')):.1f} ms (medians)"
    )


if __name__ == "__main__":
    main()
