"""How the TurtleBot3's wheels answer its commands: a delay, a first-order lag and an
acceleration limit identified from ``/cmd_vel`` and ``/joint_states``, scored on held-out time.

The wheel velocities are the joint angles' differences over each interval, between the
simulator's sample times (``io.sample_times``: 441 of the 2741 stamps are a 1 ms tick early),
and, beside them, between the stamps as recorded; the commands are
``/cmd_vel``'s twists through the robot's inverse kinematics (radii and track from the
``increments`` calibration), each held until the next. The response is identified
(``dynamics.identify_velocity_response``) on the first half of the log; on the second half,
in 5 s segments each started from its measured velocity, its prediction is compared with the
instant kinematic response (the wheels at their command at once). The figure: a held-out
segment, each wheel's measured velocity, the response's prediction and the command.

    pip install -e '.[ros,examples]'
    python examples/drive_response.py [--bags ../shared/data/ros-bags] [--output FIGURE.png]
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

import diffdrive as dd
from diffdrive import batch
from diffdrive.dynamics import identify_velocity_response
from diffdrive.io import ros

BAGS = Path(__file__).resolve().parents[2] / "shared" / "data" / "ros-bags"
ROBOT = dd.DiffDrive(left_wheel_radius=0.03256, right_wheel_radius=0.03252, track_width=0.2955)


def held_out(bags: Path, restore: bool = True) -> dict:
    """The response identified on the first half and scored on the second; ``restore``: the
    wheel velocities over the simulator's sample times (``io.sample_times``), else over the
    stamps as recorded."""
    bag = bags / "turtlebot3_fuse.bag"
    run = ros.read_joint_states(bag, "wheel_left_joint", "wheel_right_joint")
    commands = ros.read_twists(bag, "/cmd_vel")
    stamps = dd.io.sample_times(run.times).times if restore else run.times
    times = 0.5 * (stamps[1:] + stamps[:-1])
    measured = np.diff(run.wheels, axis=0) / np.diff(stamps)[:, None]
    v, omega = commands.twists.T
    wheels = batch.to_wheel_velocities(ROBOT, np.column_stack([v, 0.0 * v, omega]))
    half = len(times) // 2
    limits = (math.inf, 20.0, 40.0, 60.0, 80.0, 120.0)
    fit = identify_velocity_response(
        times[:half], measured[:half], commands.times, wheels, accelerations=limits
    )
    segment = round(float(5.0 / np.mean(np.diff(times))))
    model, instant, segments = [], [], []  # squared errors, and what the figure draws
    for start in range(half, len(times) - segment, segment):
        part = slice(start, start + segment)
        predicted = fit.predict(times[part], commands.times, wheels, measured[start])
        index = np.searchsorted(commands.times, times[part], side="right") - 1
        at_once = np.where((index >= 0)[:, None], wheels[np.maximum(index, 0)], 0.0)
        model.append((predicted - measured[part]) ** 2)
        instant.append((at_once - measured[part]) ** 2)
        segments.append((times[part], measured[part], predicted, at_once))
    return {
        "segments": segments,
        "delay": fit.delay,
        "time_constant": fit.time_constant,
        "gain": fit.gain,
        "acceleration": fit.acceleration,
        "model": float(np.sqrt(np.concatenate(model).mean())),
        "instant": float(np.sqrt(np.concatenate(instant).mean())),
        "largest": _share_of_largest(np.concatenate(model)),
    }


def _share_of_largest(squared: np.ndarray, fraction: float = 0.03) -> float:
    """The share of the squared error that the largest ``fraction`` of the errors carry."""
    ordered = np.sort(squared.ravel())[::-1]
    return float(ordered[: max(1, round(fraction * len(ordered)))].sum() / ordered.sum())


def draw(segment: tuple, output: Path) -> None:
    """One held-out segment: each wheel's measured velocity, prediction and command."""
    from matplotlib.figure import Figure

    times, measured, predicted, at_once = segment
    figure = Figure(figsize=(10, 5), layout="constrained")
    axes = figure.subplots(2, 1, sharex=True)
    for wheel, ax in enumerate(axes):
        ax.plot(times, measured[:, wheel], ".", ms=3, color="0.4", label="measured")
        ax.step(times, at_once[:, wheel], where="post", color="tab:orange", label="command")
        ax.plot(times, predicted[:, wheel], color="tab:blue", label="identified response")
        ax.set_ylabel(f"{('left', 'right')[wheel]} wheel, rad/s")
    axes[0].legend(loc="upper right")
    axes[0].set_title("TurtleBot3, held out: wheel velocity from /cmd_vel")
    axes[1].set_xlabel("bag time, s")
    figure.savefig(output, dpi=100)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bags", type=Path, default=BAGS)
    parser.add_argument("--output", type=Path, default=Path("docs/figures/drive_response.png"))
    args = parser.parse_args(argv)
    recorded, found = held_out(args.bags, restore=False), held_out(args.bags)
    print(
        f"TurtleBot3 response: delay {found['delay'] * 1000:.0f} ms, time constant "
        f"{found['time_constant'] * 1000:.0f} ms, gain {found['gain']:.3f}, acceleration "
        f"limit {found['acceleration']:g} rad/s^2"
    )
    for name, result in (("the stamps as recorded", recorded), ("the sample times", found)):
        print(
            f"held-out wheel-velocity RMSE over {name}: {result['model']:.3f} rad/s with the "
            f"response, {result['instant']:.3f} rad/s at once "
            f"({result['model'] / result['instant']:.0%}); the largest 3 % of the response's "
            f"errors carry {result['largest']:.0%} of its squared error"
        )
    args.output.parent.mkdir(parents=True, exist_ok=True)
    draw(found["segments"][2], args.output)
    print(f"figure: {args.output}")


if __name__ == "__main__":
    main()
