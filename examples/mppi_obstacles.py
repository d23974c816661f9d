"""MPPI through a cluttered corridor, behind a 0.1 s delay and a 0.1 s lag it knows.

A straight plan from one end of a 12 m x 3 m corridor to the other runs through circles; the
controller follows ``guide``'s plan around them, its 1,024 candidates a cycle scored against the
plan, the wheels' limit and the clearance grid. Prints whether the robot touched, the closest
it came (beyond its 0.35 m radius), and the time to the goal against the straight plan's; draws
the corridor, the plans, the path driven, and at three moments the candidates sampled around
the controller's mean (what Nav2 calls visualising the trajectories).

    pip install -e '.[fast,plot,maps]'
    python examples/mppi_obstacles.py [--seed 7] [--output out/figures/mppi_obstacles.png]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import diffdrive as dd
from diffdrive.control import (
    MPPI,
    Avoidance,
    FollowSettings,
    MPPISampling,
    PathLimits,
    cluttered_corridor,
    follow,
    guide,
    plan,
)
from diffdrive.dynamics import DriveModel

ROBOT = dd.DiffDrive(wheel_radius=0.1, track_width=0.6)
LIMITS = PathLimits(max_velocity=1.0, max_acceleration=1.0, max_wheel_velocity=12.0)
DRIVE = DriveModel(delay=0.1, time_constant=0.1)
FOOTPRINT, DT = 0.35, 0.05
MOMENTS = (3.0, 6.0, 9.0)  # s: when the candidates are drawn


class Recording:
    """An MPPI that keeps, at ``MOMENTS``, its candidates' positions and the pose."""

    def __init__(self, tracker: MPPI) -> None:
        self.tracker, self.samples = tracker, []

    def reset(self) -> None:
        self.tracker.reset()

    def command(self, path, t, poses):
        twist = self.tracker.command(path, t, poses)
        if any(abs(t - moment) < DT / 2 for moment in MOMENTS):
            self.samples.append((poses[0].copy(), self.tracker.sampled(path, poses[0], 48)))
        return twist


def run(seed: int):
    course = cluttered_corridor(np.random.default_rng(seed), footprint=FOOTPRINT)
    straight = plan([course.start, course.goal], ROBOT, LIMITS)
    tracker = MPPI(
        drive=DRIVE,
        sampling=MPPISampling(seed=seed),
        avoid=Avoidance(course.obstacles, footprint=FOOTPRINT),
    )
    recording = Recording(tracker)
    settle = FollowSettings(settle=0.5 * straight.duration)
    result = follow(straight, recording, dt=DT, drive=DRIVE, settings=settle)
    return course, straight, guide(straight, course.obstacles, FOOTPRINT), result, recording


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--output", type=Path, default=Path("out/figures/mppi_obstacles.png"))
    args = parser.parse_args(argv)
    course, straight, guided, result, recording = run(args.seed)
    poses = result.poses[0]
    clearance = course.clearance(poses[:, :2]) - FOOTPRINT
    reached = np.flatnonzero(np.hypot(*(poses[:, :2] - course.goal[:2]).T) < 0.1)
    print(
        f"corridor {args.seed}: touched {'yes' if (clearance < 0).any() else 'no'}, closest "
        f"{1e3 * clearance.min():.0f} mm beyond the footprint"
    )
    if len(reached):
        taken = result.times[reached[0]] - result.times[0]
        print(f"goal reached in {taken:.2f} s, {taken / straight.duration:.3f} x the straight plan")
    else:
        print("goal not reached")

    from matplotlib.figure import Figure  # no pyplot: the user's backend is left alone
    from matplotlib.patches import Circle

    figure = Figure(figsize=(12, 3.8), layout="constrained")
    axes = figure.add_subplot()
    for centre, radius in zip(course.centres, course.radii, strict=True):
        axes.add_patch(Circle(centre, radius, color="0.35"))
    for y in (-course.width / 2, course.width / 2):
        axes.axhline(y, color="0.35", linewidth=3)
    axes.plot(*straight.poses[:, :2].T, "--", color="0.6", label="plan (through the circles)")
    axes.plot(*guided.poses[:, :2].T, ":", color="tab:blue", label="guide (around them)")
    for k, (pose, candidates) in enumerate(recording.samples):
        for j, path in enumerate(candidates):
            label = "candidates sampled" if k == j == 0 else None
            axes.plot(*path.T, color="tab:orange", alpha=0.25, linewidth=0.7, label=label)
        axes.add_patch(Circle(pose[:2], FOOTPRINT, fill=False, color="tab:green"))
    axes.plot(*poses[:, :2].T, color="tab:green", label="driven (0.1 s delay, 0.1 s lag)")
    axes.set_aspect("equal")
    axes.set_xlim(-0.5, course.length + 0.5)
    axes.set_xlabel("x (m)")
    axes.set_ylabel("y (m)")
    axes.legend(loc="upper center", bbox_to_anchor=(0.5, -0.22), ncol=4, frameon=False)
    args.output.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(args.output, dpi=110)
    print(f"figure: {args.output}")


if __name__ == "__main__":
    main()
