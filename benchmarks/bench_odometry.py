"""The cost of one streaming odometry update, side by side: diffdrive vs robotpy-wpimath.

Issue 4's measure: one ``Odometry.update_positions`` call, median over 10^5 updates, next to
robotpy-wpimath's ``DifferentialDriveOdometry.update``, which takes a ``Rotation2d`` (the gyro
heading) that has to be built for every call. Both are fed the same drive, precomputed as
Python floats; each timing includes the ``for`` loop around the call, whose own cost is printed
too. The contenders run in rounds, each once a round, and the medians are over the rounds, so
a slow spell of a shared machine falls on all of them. diffdrive is also timed with time stamps
and with the covariance propagated (the C update always propagates it; here k is non-zero so
the numbers mean something), and on the pure-Python core that an installation without a C
compiler gets.

    pip install -e '.[bench]'
    python benchmarks/bench_odometry.py [--repeats 7] [--updates 100000]
"""

from __future__ import annotations

import argparse
import platform

import numpy as np

import diffdrive as dd
from diffdrive.demo import example_robot
from timing import per_call  # benchmarks/timing.py


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--updates", type=int, default=100_000)
    args = parser.parse_args()
    robot = example_robot()
    dt = 0.01
    rng = np.random.default_rng(0)
    wheels = rng.uniform(5.0, 10.0, (args.updates, 2))
    trajectory = dd.simulate(robot, wheels, dt=dt, method="exact")
    angles = trajectory.wheel_positions[1:]
    left, right = angles[:, 0].tolist(), angles[:, 1].tolist()
    times = trajectory.times[1:].tolist()
    headings = trajectory.poses[1:, 2].tolist()
    left_m = (angles[:, 0] * robot.left_wheel_radius).tolist()
    right_m = (angles[:, 1] * robot.right_wheel_radius).tolist()
    n = args.updates

    def empty():
        for _ in zip(left, right, strict=True):
            pass
        return n

    def ours(kind=dd.Odometry, **options):
        def loop():
            odometry = kind(robot, **options)
            update = odometry.update_positions
            for a, b in zip(left, right, strict=True):
                update(a, b)
            return n

        return loop

    def ours_timed():
        odometry = dd.Odometry(robot, wheel_noise=1e-4)
        update = odometry.update_positions
        for a, b, t in zip(left, right, times, strict=True):
            update(a, b, t)
        return n

    loops = {
        "empty loop": empty,
        "diffdrive update_positions": ours(),
        "  with wheel noise": ours(wheel_noise=1e-4),
        "  with k and t": ours_timed,
        "  on the pure-Python core (no C compiler)": ours(dd.estimation.odometry._PythonOdometry),
    }
    try:
        from wpimath.geometry import Pose2d, Rotation2d
        from wpimath.kinematics import DifferentialDriveOdometry
    except ImportError:
        print("robotpy-wpimath is not installed: pip install -e '.[bench]'")
    else:

        def theirs():
            odometry = DifferentialDriveOdometry(Rotation2d(0.0), 0.0, 0.0, Pose2d())
            update = odometry.update
            for heading, a, b in zip(headings, left_m, right_m, strict=True):
                update(Rotation2d(heading), a, b)
            return n

        loops["wpimath DifferentialDriveOdometry.update"] = theirs
    rows = per_call(loops, args.repeats)
    print(
        f"machine: {platform.machine()}, {platform.processor() or 'cpu'}; "
        f"python {platform.python_version()}"
    )
    print(f"median of {args.repeats} runs of {n} updates; ns per update, loop included\n")
    ours_time = rows["diffdrive update_positions"]
    for name, seconds in rows.items():
        ratio = f"{seconds / ours_time:6.2f} x diffdrive's time" if name != "empty loop" else ""
        print(f"  {name:42} {seconds * 1e9:8.1f}   {ratio}")


if __name__ == "__main__":
    main()
