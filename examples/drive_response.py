"""How the TurtleBot3's wheels answer its commands: a delay, a first-order lag and an
acceleration limit identified from ``/cmd_vel`` and ``/joint_states``, scored on held-out time.

The wheel velocities are the joint angles' differences over each interval, between the
simulator's sample times (``io.sample_times``: 441 of the 2741 stamps are a 1 ms tick early),
and, beside them, between the stamps as recorded; the commands are ``/cmd_vel``'s twists
through the robot's inverse kinematics (radii and track from the ``increments``
calibration), each held until the next. ``dynamics.cross_validate_response`` cuts the log into
``--folds`` blocks (5); each is held out in turn, the response identified on the rest, and
the block predicted in 5 s segments, each started from its measured velocity, beside the
instant kinematic response (the wheels at their command at once). The figure: a held-out
segment, each wheel's measured velocity, the response's prediction and the command.

    pip install -e '.[ros,examples]'
    python examples/drive_response.py [--bags ../shared/data/ros-bags] [--output FIGURE.png]
        [--folds 5]
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

import diffdrive as dd
from diffdrive import batch
from diffdrive.dynamics import cross_validate_response
from diffdrive.io import ros

BAGS = Path(__file__).resolve().parents[2] / "shared" / "data" / "ros-bags"
ROBOT = dd.DiffDrive(left_wheel_radius=0.03256, right_wheel_radius=0.03252, track_width=0.2955)


def held_out(bags: Path, restore: bool = True, folds: int = 5) -> dict:
    """The response scored by ``dynamics.cross_validate_response``: the log cut into ``folds``
    blocks, each scored in 5 s segments by the response identified on the others; ``restore``: the
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
    limits = (math.inf, 20.0, 40.0, 60.0, 80.0, 120.0)
    found = cross_validate_response(
        times, measured, commands.times, wheels, folds=folds, segment=5.0, accelerations=limits
    )
    scored = ~np.isnan(found.predicted)
    # The figure's segment: the last whole 5 s piece of the block that holds the log's middle.
    piece = round(5.0 / float(np.mean(np.diff(times))))
    bounds = np.linspace(0, len(times), folds + 1).round().astype(int)
    block = int(np.searchsorted(bounds, len(times) // 2, side="right")) - 1
    first = bounds[block] + ((bounds[block + 1] - bounds[block]) // piece - 1) * piece
    shown = slice(first, first + piece)
    return {
        "found": found,
        "segment": (times[shown], measured[shown], found.predicted[shown], found.at_once[shown]),
        "largest": _share_of_largest((found.predicted - measured)[scored] ** 2),
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
    parser.add_argument("--output", type=Path, default=Path("out/figures/drive_response.png"))
    parser.add_argument("--folds", type=int, default=5, help="blocks held out in turn")
    args = parser.parse_args(argv)
    recorded = held_out(args.bags, restore=False, folds=args.folds)
    restored = held_out(args.bags, folds=args.folds)
    for fold, response in enumerate(restored["found"].responses, 1):
        print(
            f"fold {fold}'s response (identified on the others): delay "
            f"{response.delay * 1000:.0f} ms, time constant {response.time_constant * 1000:.0f} "
            f"ms, gain {response.gain:.3f}, acceleration limit {response.acceleration:.1f} "
            "rad/s^2"
        )
    for name, result in (("the stamps as recorded", recorded), ("the sample times", restored)):
        found = result["found"]
        each = ", ".join(
            f"{a / b:.0%} ({a:.2f} against {b:.2f} rad/s)"
            for a, b in zip(found.rmse, found.instant, strict=True)
        )
        print(
            f"held-out wheel-velocity RMSE over {name}, {args.folds} folds: {found.pooled:.3f} "
            f"rad/s with the response, {found.pooled_instant:.3f} rad/s at once "
            f"({found.ratio:.1%}; fold by fold {each}); the largest 3 % of the response's "
            f"errors carry {result['largest']:.0%} of its squared error"
        )
    args.output.parent.mkdir(parents=True, exist_ok=True)
    draw(restored["segment"], args.output)
    print(f"figure: {args.output}")


if __name__ == "__main__":
    main()
