"""Planning within every wheel's limits: diffdrive's plan against robotpy-wpimath's
TrajectoryGenerator, side by side on the same paths in one run.

The robot of allwpilib#2296: track 0.6889 m, kS 1.34 V, kV 3.13 V s/m, kA 0.926 V s^2/m per
wheel, 10 V, wheels at most 2.5 m/s, TrajectoryConfig(3 m/s, 2 m/s^2) with wpimath's
DifferentialDriveKinematicsConstraint and DifferentialDriveVoltageConstraint. diffdrive gets the
same limits (the wheel radius, 0.0762 m here, only converts m/s at the rim into the rad/s
diffdrive's wheels are stated in; the figures do not depend on it).

The paths: random 2-4 waypoints (x, y) in an 8 m square, at least 1 m apart, each heading the
way the path goes (from the waypoint before to the one after) turned by up to 45 degrees,
until wpimath has accepted 300 (it refuses splines it finds malformed); both libraries join the
poses with the same quintic Hermite splines (tangents 1.2 times the chord), which the
benchmark checks. Every state of both is judged by one measure (``limit_ratios``): wheel
velocities from each state's twist, wheel accelerations from the differences between states,
voltages through the feedforward. Printed: the states over any limit by more than 1 %, the
worst voltage, and the total time against wpimath's on the paths where wpimath stays within
1 % (so a fast plan that breaks the limits is not counted as fast).

Jerk: the first 100 of those paths again with a jerk limit of 20 and of 5 m/s^3: plans
refused, states over any limit (jerk included) by more than 1e-9, and the total time against
the plan without the jerk limit.

Tracking: the trajectory of WPILib's LTVUnicycleControllerTest (2 waypoints, 8.8 m/s,
0.1 m/s^2, about 30 s) followed with commands 0.1 s late through a 0.1 s first-order lag
(``follow``, no noise, from the plan's start), by wpimath's RamseteController and
LTVUnicycleController (the test's tuning) and by diffdrive's, plain and ``Predictive``. Printed:
the mean and maximum distance to the reference position of the same time, and each tracker's
delay margin by simulation with that lag.

Speed: the median time to plan one 4-waypoint path, each library in turn in rounds; and 2,000
rollouts of 56 steps with acceleration limits and 2 steps of delay (``rollouts``, one cycle of
Nav2's MPPI).

    pip install -e '.[bench]'
    python benchmarks/bench_planning.py [--paths 300]
"""

from __future__ import annotations

import argparse
import math
import platform

import numpy as np

import diffdrive as dd
from diffdrive.control import PathLimits, limit_ratios, plan
from diffdrive.dynamics import Feedforward
from timing import per_call  # benchmarks/timing.py

TRACK, RADIUS = 0.6889, 0.0762
KS, KV, KA, VOLTS, WHEEL, VMAX, AMAX = 1.34, 3.13, 0.926, 10.0, 2.5, 3.0, 2.0
ROBOT = dd.DiffDrive(wheel_radius=RADIUS, track_width=TRACK)
LIMITS = PathLimits(
    max_velocity=VMAX,
    max_acceleration=AMAX,
    max_wheel_velocity=WHEEL / RADIUS,
    max_voltage=VOLTS,
    feedforward=Feedforward(KS, KV * RADIUS, KA * RADIUS),  # per rad/s of the wheel
)
TOLERANCE = 1.01


def wpimath_config():
    from wpimath.controller import SimpleMotorFeedforwardMeters
    from wpimath.kinematics import DifferentialDriveKinematics
    from wpimath.trajectory import TrajectoryConfig
    from wpimath.trajectory.constraint import (
        DifferentialDriveKinematicsConstraint,
        DifferentialDriveVoltageConstraint,
    )

    kinematics = DifferentialDriveKinematics(TRACK)
    config = TrajectoryConfig(VMAX, AMAX)
    config.setKinematics(kinematics)
    feedforward = SimpleMotorFeedforwardMeters(KS, KV, KA)
    config.addConstraint(DifferentialDriveVoltageConstraint(feedforward, kinematics, VOLTS))
    config.addConstraint(DifferentialDriveKinematicsConstraint(kinematics, WHEEL))
    return config


def wpimath_plan(waypoints, config):
    from wpimath.geometry import Pose2d, Rotation2d
    from wpimath.trajectory import TrajectoryGenerator

    poses = [Pose2d(x, y, Rotation2d(theta)) for x, y, theta in waypoints]
    return TrajectoryGenerator.generateTrajectory(poses, config)


def wpimath_states(trajectory) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """times, twists ``(v, omega)``, positions of a wpimath trajectory."""
    rows = [
        (s.t, s.velocity, s.velocity * s.curvature, s.pose.X(), s.pose.Y())
        for s in trajectory.states()
    ]
    table = np.array(rows)
    return table[:, 0], table[:, 1:3], table[:, 3:5]


def random_waypoints(rng: np.random.Generator) -> np.ndarray:
    count = int(rng.integers(2, 5))
    while True:
        points = rng.uniform(0.0, 8.0, size=(count, 2))
        if np.all(np.hypot(*np.diff(points, axis=0).T) >= 1.0):
            # Headings along the way the path goes (Catmull-Rom's), turned by up to 45 degrees.
            before = np.concatenate([points[:1], points[:-1]])
            after = np.concatenate([points[1:], points[-1:]])
            along = np.arctan2(*(after - before).T[::-1])
            return np.column_stack([points, along + rng.uniform(-0.25, 0.25, count) * math.pi])


def worst(ratios: dict[str, np.ndarray]) -> np.ndarray:
    return np.max(np.stack(list(ratios.values())), axis=0)


def compare(paths: int, seed: int = 1) -> None:
    from importlib.metadata import version

    import wpimath  # noqa: F401, the peer must be there

    config = wpimath_config()
    rng = np.random.default_rng(seed)
    accepted = refused_theirs = refused_ours = 0
    theirs_over = theirs_states = theirs_paths_over = 0
    ours_over = ours_states = 0
    worst_volts = [0.0, 0.0]
    time_ratios, gap = [], 0.0
    while accepted < paths:
        waypoints = random_waypoints(rng)
        try:
            theirs = wpimath_plan(waypoints, config)
        except Exception:  # wpimath's MalformedSplineException and kin
            refused_theirs += 1
            continue
        accepted += 1
        times, twists, positions = wpimath_states(theirs)
        ratios = limit_ratios(times, twists, ROBOT, LIMITS)
        over = worst(ratios) > TOLERANCE
        theirs_over += int(over.sum())
        theirs_states += len(times)
        theirs_paths_over += bool(over.any())
        worst_volts[0] = max(worst_volts[0], float(ratios["voltage"].max()) * VOLTS)
        try:
            ours = plan(waypoints, ROBOT, LIMITS)
        except ValueError:
            refused_ours += 1
            continue
        ours_ratios = limit_ratios(ours.times, ours.twists, ROBOT, LIMITS)
        ours_over += int((worst(ours_ratios) > TOLERANCE).sum())
        ours_states += len(ours.times)
        worst_volts[1] = max(worst_volts[1], float(ours_ratios["voltage"].max()) * VOLTS)
        # Same curve: wpimath's states lie on ours.
        distance = np.hypot(*(positions[:, None, :] - ours.poses[None, :, :2]).transpose(2, 0, 1))
        gap = max(gap, float(distance.min(axis=1).max()))
        if not over.any():
            time_ratios.append(ours.duration / theirs.totalTime())
    print(
        f"{paths} paths wpimath accepted ({refused_theirs} refused as malformed); "
        f"diffdrive refused {refused_ours} of them; wpimath {version('robotpy-wpimath')}"
    )
    print(f"the curves agree: wpimath's states lie within {gap * 1e3:.2f} mm of diffdrive's path")
    print(
        f"states over a limit by more than 1 %: wpimath {theirs_over} of {theirs_states} "
        f"(on {theirs_paths_over} paths), diffdrive {ours_over} of {ours_states}"
    )
    print(f"worst wheel voltage: wpimath {worst_volts[0]:.1f} V, diffdrive {worst_volts[1]:.2f} V")
    ratios = np.array(time_ratios)
    spread = f"median {np.median(ratios):.3f}, max {ratios.max():.3f}" if len(ratios) else "-"
    print(
        f"total time, diffdrive / wpimath, on the {len(ratios)} paths wpimath keeps within limits: "
        + spread
    )


def samples(paths: int = 100, seed: int = 1, step: float = 0.005) -> None:
    """``Plan.sample`` every ``step`` s on random paths, judged as states (the accelerations
    its consecutive samples imply, the voltage with them): how many samples break a limit by
    more than 0.1 % (target 0)."""
    rng = np.random.default_rng(seed)
    over = total = made = 0
    worst_ratio = 0.0
    while made < paths:
        try:
            ours = plan(random_waypoints(rng), ROBOT, LIMITS)
        except ValueError:
            continue
        made += 1
        t = np.arange(ours.times[0], ours.times[-1], step)
        ratios = limit_ratios(t, ours.sample(t)["twist"], ROBOT, LIMITS)
        over += int((worst(ratios) > 1.001).sum())
        total += len(t)
        worst_ratio = max(worst_ratio, float(worst(ratios).max()))
    print(
        f"Plan.sample every {step * 1e3:g} ms on {paths} paths: {over} of {total} samples over "
        f"a limit by more than 0.1 % (target 0); the worst at {100 * worst_ratio:.2f} %"
    )


class _Peer:
    """A wpimath controller behind ``follow``'s tracker interface (one robot)."""

    def __init__(self, controller) -> None:
        self.controller = controller

    def command(self, plan_, t, poses):
        from wpimath.geometry import Pose2d, Rotation2d

        ref = plan_.sample(t)
        x, y, theta = ref["pose"]
        out = []
        for pose in poses:
            speeds = self.controller.calculate(
                Pose2d(pose[0], pose[1], Rotation2d(pose[2])),
                Pose2d(x, y, Rotation2d(theta)),
                float(ref["twist"][0]),
                float(ref["twist"][1]),
            )
            out.append((speeds.vx, speeds.omega))
        return np.array(out)


def jerk(paths: int = 100, seed: int = 1) -> None:
    from dataclasses import replace

    config = wpimath_config()
    for limit in (20.0, 5.0):
        limits = replace(LIMITS, max_jerk=limit)
        rng = np.random.default_rng(seed)
        done = refused = over = 0
        ratios = []
        while done < paths:
            waypoints = random_waypoints(rng)
            try:
                wpimath_plan(waypoints, config)
            except Exception:  # the same paths as above
                continue
            done += 1
            try:
                fastest = plan(waypoints, ROBOT, LIMITS)
            except ValueError:
                continue
            try:
                smooth = plan(waypoints, ROBOT, limits)
            except ValueError:
                refused += 1
                continue
            over += int(
                (worst(limit_ratios(smooth.times, smooth.twists, ROBOT, limits)) > 1 + 1e-9).sum()
            )
            ratios.append(smooth.duration / fastest.duration)
        print(
            f"jerk {limit:g} m/s^3 on {paths} paths: {refused} refused, {over} states over a "
            f"limit; time against no jerk limit: median {np.median(ratios):.3f}, "
            f"max {np.max(ratios):.3f}"
        )


def tracking() -> None:
    from wpimath.controller import LTVUnicycleController, RamseteController

    from diffdrive.control import LTVUnicycle, Predictive, Ramsete, delay_margin, follow

    robot = dd.DiffDrive(wheel_radius=0.1, track_width=0.6)
    reference = plan(
        [(2.75, 22.521, 0.0), (24.73, 19.68, 5.846)],
        robot,
        PathLimits(max_velocity=8.8, max_acceleration=0.1),
    )
    q, r = (0.0625, 0.125, 2.5), (4.0, 4.0)
    trackers = {
        "wpimath Ramsete (2, 0.7)": _Peer(RamseteController()),
        "wpimath LTV unicycle (test tuning)": _Peer(LTVUnicycleController(q, r, 0.02)),
        "diffdrive Ramsete (2, 0.7)": Ramsete(),
        "diffdrive LTVUnicycle (test tuning)": LTVUnicycle(q, r),
        "diffdrive Predictive(Ramsete)": Predictive(Ramsete(), 0.1, 0.02, 0.1),
        "diffdrive Predictive(LTVUnicycle)": Predictive(LTVUnicycle(q, r), 0.1, 0.02, 0.1),
    }
    print(f"tracking {reference.duration:.1f} s with 0.1 s delay and 0.1 s lag:")
    for name, tracker in trackers.items():
        summary = follow(reference, tracker, delay=0.1, lag=0.1).errors().summary()
        known = 0.1 if name.startswith("diffdrive Predictive") else 0.0
        margin = delay_margin(reference, tracker, lag=0.1, known=known, max_delay=0.3)
        beyond = " beyond its 0.1 s" if known else ""
        error = (
            f"mean {1e3 * summary['mean_position']:.1f} mm, "
            f"max {1e3 * summary['max_position']:.1f} mm"
            if summary["max_position"] < 1.0
            else "diverges"
        )
        print(f"  {name}: {error}; delay margin{beyond} {margin:.2f} s")


def rollout_speed(repeats: int) -> None:
    from diffdrive.control import rollouts
    from timing import median_time

    rng = np.random.default_rng(0)
    commands = rng.normal(0.5, 0.3, (2000, 56, 2))

    def work():
        return rollouts(
            (0.0, 0.0, 0.0),
            commands,
            0.05,
            in_flight=[(0.4, 0.1), (0.4, 0.1)],
            current=(0.4, 0.1),
            max_acceleration=(3.0, 3.2),
        )

    taken = median_time(work, repeats * 3, warm_up=True)
    print(f"2,000 rollouts of 56 steps with acceleration limits and delay: {taken * 1e3:.2f} ms")


def speed(repeats: int) -> None:
    config = wpimath_config()
    waypoints = np.array([(0.0, 0.0, 0.0), (3.0, 1.0, 0.5), (5.0, 4.0, 1.5), (2.0, 6.0, 3.0)])
    plan(waypoints, ROBOT, LIMITS)  # compiles the kernel where numba is installed

    def ours() -> int:
        for _ in range(20):
            plan(waypoints, ROBOT, LIMITS)
        return 20

    def theirs() -> int:
        for _ in range(20):
            wpimath_plan(waypoints, config)
        return 20

    taken = per_call({"diffdrive": ours, "wpimath": theirs}, repeats)
    print(
        f"planning a 4-waypoint path: diffdrive {taken['diffdrive'] * 1e3:.3f} ms, wpimath "
        f"{taken['wpimath'] * 1e3:.3f} ms (ratio {taken['diffdrive'] / taken['wpimath']:.2f})"
    )


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--paths", type=int, default=300, help="compared; at most 100 sampled")
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args(argv)
    print(f"machine: {platform.processor() or platform.machine()}, {platform.python_version()}")
    compare(args.paths)
    samples(min(args.paths, 100))
    jerk(min(args.paths, 100))
    tracking()
    speed(args.repeats)
    rollout_speed(args.repeats)


if __name__ == "__main__":
    main()
