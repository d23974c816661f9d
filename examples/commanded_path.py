"""The path a robot is commanded to drive, and the path it drives once its limits apply.

A joystick-like sequence of twist commands at 50 Hz: full speed ahead with sharp turns, a
sudden stop, a burst in reverse, then silence (the timeout stops the robot). The commanded
path integrates the commands as given; the limited path sends them through a
velocity/acceleration/jerk ``Limiter`` and wheel desaturation first (``drive_commands``), which
is what the robot would do. Prints the end points and draws both paths and the forward speed.

    pip install -e '.[plot]'
    python examples/commanded_path.py [--output out/figures/commanded_path.png]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import diffdrive as dd
from diffdrive.demo import example_robot

DT = 0.02  # s
ROBOT = example_robot()
MAX_WHEEL_VELOCITY = 20.0  # rad/s: 0.84 m/s at the rim


def commands() -> np.ndarray:
    """``(T, 2)`` twist commands ``(v, omega)``; rows of NaN: no command that cycle."""
    t = np.arange(round(14.0 / DT)) * DT
    v = np.select([t < 6, t < 7, t < 9.5, t < 11], [1.0, 0.0, -0.6, 0.0], default=np.nan)
    omega = np.select(
        [t < 2, t < 4, t < 6, t < 7, t < 9.5, t < 11], [0.0, 3.0, -3.0, 0.0, 1.5, 0.0], np.nan
    )
    return np.stack([v, omega], axis=-1)


def limiter() -> dd.Limiter:
    return dd.Limiter.for_twist(
        dd.Limits(
            max_velocity=0.7,
            max_reverse_velocity=0.3,
            max_acceleration=0.8,
            max_deceleration=1.5,
            max_jerk=6.0,
        ),
        dd.Limits(max_velocity=2.5, max_acceleration=4.0, max_jerk=30.0),
        timeout=0.5,
    )


def paths() -> tuple[dd.Trajectory, dd.Trajectory]:
    """The commanded and the limited trajectory."""
    sequence = commands()
    given = np.nan_to_num(sequence)  # as commanded: silence is standing still
    twists = np.stack([given[:, 0], np.zeros(len(given)), given[:, 1]], axis=-1)
    commanded = dd.simulate(ROBOT, dd.batch.to_wheel_velocities(ROBOT, twists), dt=DT)
    limited = dd.drive_commands(
        ROBOT, sequence, DT, limiter(), max_wheel_velocity=MAX_WHEEL_VELOCITY
    )
    return commanded, limited


def draw(commanded: dd.Trajectory, limited: dd.Trajectory, output: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, (path, speed) = plt.subplots(1, 2, figsize=(11, 4.5), layout="constrained")
    for trajectory, label, style in [(commanded, "commanded", "--"), (limited, "limited", "-")]:
        x, y = trajectory.poses[:, 0], trajectory.poses[:, 1]
        path.plot(x, y, style, label=label)
        path.plot(x[-1], y[-1], "o", color=path.lines[-1].get_color())
        speed.step(trajectory.times[:-1], trajectory.twists[:, 0], style, where="post", label=label)
    path.plot(0, 0, "k^", label="start")
    path.set_aspect("equal", adjustable="datalim")
    path.set(xlabel="x, m", ylabel="y, m", title="path")
    path.legend()
    speed.set(xlabel="t, s", ylabel="forward speed v, m/s", title="forward speed")
    speed.grid(True, alpha=0.3)
    figure.savefig(output, dpi=100)
    plt.close(figure)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", type=Path, default=Path("out/figures/commanded_path.png"))
    args = parser.parse_args(argv)
    commanded, limited = paths()
    for name, trajectory in [("commanded", commanded), ("limited", limited)]:
        x, y, theta = trajectory.final_pose
        print(f"{name:9} ends at x {x:6.3f} m, y {y:6.3f} m, heading {np.degrees(theta):7.1f} deg")
    peak = np.abs(limited.wheel_velocities).max()
    print(f"limited: largest wheel velocity {peak:.2f} rad/s (limit {MAX_WHEEL_VELOCITY})")
    args.output.parent.mkdir(parents=True, exist_ok=True)
    draw(commanded, limited, args.output)
    print(f"figure: {args.output}")


if __name__ == "__main__":
    main()
