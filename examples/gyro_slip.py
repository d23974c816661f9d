"""A gyro against slipping wheels: a synthetic run with known slip, and a real Husky with GPS.

- Synthetic: 60 s of weaving with three 0.5 s episodes in which the left wheel spins faster than
  the ground moves, and a 100 Hz gyro whose bias drifts from 0.01 to 0.03 rad/s. The position
  error of each heading source against the truth, and how many slipping intervals the
  chi-square test flags (and how many it flags that do not slip).
- Husky (``husky_robot_localization_test1.bag``): the wheel travel and heading change of each
  interval from the drive controller's odometry, the gyro from ``/imu/data`` (mounted with
  its y axis up: roll 90 degrees), and each heading source's path against GPS, positions only,
  after the best SE(2) alignment.

    pip install -e '.[ros,plot]'
    python examples/gyro_slip.py [--bags ../shared/data/ros-bags] [--output FIGURE.png]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

import diffdrive as dd
from diffdrive.estimation import EstimatorSettings
from diffdrive.estimation.gyro import HEADINGS, Gyro, gyro_odometry
from diffdrive.evaluation import align, ate, interpolate

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the Husky's reading is shared
from husky_fusion import BAGS, HUSKY
from husky_fusion import read as read_husky

ROBOT = dd.DiffDrive(wheel_radius=0.05, track_width=0.3)


def synthetic(seed: int = 0) -> dict:
    """The synthetic run: each source's trajectory, the truth and the slip mask."""
    rng = np.random.default_rng(seed)
    dt, n = 0.02, 3000
    t = np.arange(n + 1) * dt
    wheels = np.stack([6 + 2 * np.sin(0.3 * t[:-1]), 6 - 2 * np.sin(0.21 * t[:-1] + 1)], -1)
    wheels[:50] = 0.0  # standing still for a second: the gyro bias to start from
    truth = dd.simulate(ROBOT, wheels, dt=dt)
    measured = wheels * dt
    slip = np.zeros(n, dtype=bool)
    for start in (600, 1400, 2200):
        slip[start : start + 25] = True
    measured[slip, 0] += 0.25
    measured[50:] += rng.normal(0, 0.002, measured[50:].shape)
    gyro_times = np.arange(0, t[-1] + 1e-9, 0.01)
    rates = np.concatenate([truth.twists[:, 2], truth.twists[-1:, 2]])
    bias = 0.01 + 0.02 * gyro_times / gyro_times[-1]
    noisy = np.interp(gyro_times, truth.times, rates) + bias
    gyro = Gyro(gyro_times, noisy + rng.normal(0, 0.02, len(gyro_times)))
    runs = {
        h: gyro_odometry(ROBOT, t, measured, gyro, EstimatorSettings(h, wheel_noise=2e-6))
        for h in HEADINGS
    }
    return {"runs": runs, "truth": truth, "slip": slip}


def husky(bags: Path) -> dict:
    """Each source's Husky path, aligned to GPS, and its ATE (m)."""
    data = read_husky(bags)
    truth = np.column_stack([data["fixes"], np.zeros(len(data["fixes"]))])
    found = {"truth": truth}
    for heading in HEADINGS:
        run = gyro_odometry(
            HUSKY,
            data["times"],
            data["increments"],
            data["gyro"],
            EstimatorSettings(heading, wheel_noise=1e-3),
            initial_pose=data["start"],
        )
        estimate = interpolate(data["times"], run.poses, data["fix_times"])
        estimate[:, 2] = 0.0  # positions only
        found[heading] = (align(estimate, truth), ate(estimate, truth, aligned=True))
    return found


def draw(synthetic_runs: dict, husky_runs: dict, output: Path) -> None:
    from matplotlib.figure import Figure

    figure = Figure(figsize=(12, 5), layout="constrained")
    left, right = figure.subplots(1, 2)
    truth = synthetic_runs["truth"].poses
    left.plot(truth[:, 0], truth[:, 1], color="0.6", linewidth=3, label="truth")
    for heading, run in synthetic_runs["runs"].items():
        left.plot(run.poses[:, 0], run.poses[:, 1], label=f"heading: {heading}")
    flagged = synthetic_runs["runs"]["fused"].slip
    left.plot(*truth[flagged, :2].T, "x", color="tab:red", label="flagged: slip")
    left.set_aspect("equal", adjustable="datalim")
    left.set(xlabel="x, m", ylabel="y, m", title="synthetic: three slips, a drifting gyro bias")
    left.legend(loc="best")
    right.plot(*husky_runs["truth"][:, :2].T, ".", color="0.5", markersize=3, label="GPS")
    for heading in HEADINGS:
        aligned, error = husky_runs[heading]
        right.plot(*aligned[:, :2].T, label=f"{heading}: ATE {error:.2f} m")
    right.set_aspect("equal", adjustable="datalim")
    right.set(xlabel="east, m", ylabel="north, m", title="Husky: each heading against GPS")
    right.legend(loc="best")
    for ax in (left, right):
        ax.grid(True, alpha=0.3)
    figure.savefig(output, dpi=100)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bags", type=Path, default=BAGS)
    parser.add_argument("--output", type=Path, default=Path("out/figures/gyro_slip.png"))
    args = parser.parse_args(argv)
    runs = synthetic()
    truth, slip = runs["truth"], runs["slip"]
    print("synthetic run, largest position error against the truth:")
    for heading, run in runs["runs"].items():
        error = np.hypot(*(run.poses[:, :2] - truth.poses[:, :2]).T).max()
        flags = run.slip[1:]
        print(
            f"  {heading:6} {error:6.2f} m; slip flagged on {flags[slip].mean():.0%} of the "
            f"slipping intervals, {flags[~slip].mean():.2%} of the others"
        )
    found = husky(args.bags)
    print(
        "Husky against GPS, SE(2)-aligned ATE: "
        + ", ".join(f"{heading} {found[heading][1]:.2f} m" for heading in HEADINGS)
    )
    args.output.parent.mkdir(parents=True, exist_ok=True)
    draw(runs, found, args.output)
    print(f"figure: {args.output}")


if __name__ == "__main__":
    main()
