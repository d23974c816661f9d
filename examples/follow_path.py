"""A path planned within every wheel's limits, then followed through delay, lag and noisy odometry.

Four waypoints for a 0.6 m-track robot with 0.1 m wheels: the plan keeps each wheel under
25 rad/s, 30 rad/s^2 and, through its feedforward (kS 1.34 V, kV 0.313 V s/rad, kA 0.0926
V s^2/rad), 10 V. Then 50 robots follow it with commands 0.1 s late, wheels that lag 0.1 s and
wheel odometry with noise k = 1e-4 m per wheel, each with the LTV tracker wrapped in
``Predictive``. Prints how much of each limit the plan uses and the tracking errors; draws the
path with the runs, and each wheel's velocity and voltage against its limit.

    pip install -e '.[plot,control]'
    python examples/follow_path.py [--output out/figures/follow_path.png]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import diffdrive as dd
from diffdrive.control import (
    FollowSettings,
    LTVUnicycle,
    PathLimits,
    Predictive,
    follow,
    limit_ratios,
    plan,
)
from diffdrive.dynamics import Feedforward

ROBOT = dd.DiffDrive(wheel_radius=0.1, track_width=0.6)
WAYPOINTS = np.array([(0.0, 0.0, 0.0), (3.0, 1.0, 0.6), (4.0, 3.5, 2.2), (1.0, 4.0, 3.1)])
LIMITS = PathLimits(
    max_velocity=2.0,
    max_acceleration=2.0,
    max_wheel_velocity=25.0,
    max_wheel_acceleration=30.0,
    max_voltage=10.0,
    feedforward=Feedforward(1.34, 0.313, 0.0926),
)
DELAY, LAG, NOISE, ROBOTS = 0.1, 0.1, 1e-4, 50


def run():
    planned = plan(WAYPOINTS, ROBOT, LIMITS)
    tracker = Predictive(LTVUnicycle(), delay=DELAY, dt=0.02, lag=LAG)
    followed = follow(
        planned,
        tracker,
        delay=DELAY,
        lag=LAG,
        settings=FollowSettings(robots=ROBOTS, wheel_noise=(NOISE, NOISE), seed=1),
    )
    return planned, followed


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", type=Path, default=Path("out/figures/follow_path.png"))
    args = parser.parse_args(argv)
    planned, followed = run()
    print(
        f"plan: {planned.duration:.2f} s over {planned.length:.2f} m, {len(planned.times)} states"
    )
    for name, ratio in limit_ratios(planned.times, planned.twists, ROBOT, LIMITS).items():
        print(f"  {name}: at most {100 * ratio.max():.1f} % of its limit")
    errors = followed.errors()
    print(
        f"followed by {ROBOTS} robots: cross-track error mean "
        f"{1e3 * np.abs(errors.cross_track).mean():.1f} mm, max "
        f"{1e3 * np.abs(errors.cross_track).max():.1f} mm (odometry noise, not seen by the tracker)"
    )
    from diffdrive.plot import plot_plan

    args.output.parent.mkdir(parents=True, exist_ok=True)
    plot_plan(planned, args.output, followed)
    print(f"figure: {args.output}")


if __name__ == "__main__":
    main()
