"""Two real robots' bags: a TurtleBot3 calibrated from its joint states, and a Husky's wheel
odometry against GPS.

- TurtleBot3 (simulated, ``turtlebot3_fuse.bag``): calibrate the wheel radii and track from
  ``/joint_states`` with ``/odom`` as the reference (method ``increments``), dead-reckon with
  the calibrated robot, and compare with ``/odom``.
- Husky (real, outdoors, ``husky_robot_localization_test1.bag``): the drive controller's wheel
  odometry against GPS, converted to a local east-north frame, compared on positions only
  after the best rigid SE(2) alignment (the GPS has no heading; about 0.9 m noise).

Prints the figures and draws both. Needs the bags in ../shared/data/ros-bags beside the clone.

    pip install -e '.[ros,plot,examples]'
    python examples/ros_bags.py [--bags ../shared/data/ros-bags] [--output FIGURE.png]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import diffdrive as dd
from diffdrive.calibration import calibrate
from diffdrive.evaluation import align, ate, interpolate, run_errors
from diffdrive.io import read_run, ros
from diffdrive.simulation import dead_reckon

BAGS = Path(__file__).resolve().parents[2] / "shared" / "data" / "ros-bags"
NOMINAL_TB3 = dd.DiffDrive(wheel_radius=0.033, track_width=0.287)  # the Waffle's datasheet
HUSKY_ODOMETRY = "/husky_velocity_controller/odom"


def turtlebot3(bags: Path) -> dict:
    """Calibration against /odom, and the dead reckoning it gives."""
    log = read_run(
        bags / "turtlebot3_fuse.bag",
        left_joint="wheel_left_joint",
        right_joint="wheel_right_joint",
        reference_topic="/odom",
    )
    increments = log.increments()
    result = calibrate(NOMINAL_TB3, [log], "increments")
    found = {}
    for name, robot in (("nominal", NOMINAL_TB3), ("calibrated", result.robot)):
        poses = dead_reckon(robot, increments, log.truth[0])
        found[name] = (poses, run_errors(poses, log.truth))
    return {"log": log, "result": result, "runs": found}


def husky(bags: Path) -> dict:
    """The wheel odometry at the GPS times, raw and aligned, against the GPS positions."""
    bag = bags / "husky_robot_localization_test1.bag"
    odometry = ros.read_odometry(bag, HUSKY_ODOMETRY)
    gps = ros.read_navsatfix(bag, "/fix")
    inside = (gps.times >= odometry.times[0]) & (gps.times <= odometry.times[-1])
    estimate = interpolate(odometry.times, odometry.poses, gps.times[inside])
    estimate[:, 2] = 0.0  # positions only: the GPS has no heading
    truth = np.column_stack([gps.positions[inside], np.zeros(np.count_nonzero(inside))])
    travelled = float(np.sum(np.hypot(*np.diff(odometry.poses[:, :2], axis=0).T)))
    return {
        "truth": truth,
        "estimate": estimate,
        "aligned": align(estimate, truth),
        "ate": ate(estimate, truth),
        "ate_aligned": ate(estimate, truth, aligned=True),
        "travelled": travelled,
    }


def draw(tb3: dict, gps: dict, output: Path) -> None:
    from matplotlib.figure import Figure

    figure = Figure(figsize=(12, 5), layout="constrained")
    left, right = figure.subplots(1, 2)
    truth = tb3["log"].truth
    left.plot(truth[:, 0], truth[:, 1], color="0.6", linewidth=3, label="/odom (reference)")
    for name, style in (("nominal", "--"), ("calibrated", "-")):
        poses = tb3["runs"][name][0]
        left.plot(poses[:, 0], poses[:, 1], style, label=f"joint states, {name}")
    left.set_aspect("equal", adjustable="datalim")
    left.set(xlabel="x, m", ylabel="y, m", title="TurtleBot3: dead reckoning against /odom")
    left.legend(loc="best")
    right.plot(*gps["truth"][:, :2].T, ".", color="0.5", markersize=3, label="GPS (local E, N)")
    right.plot(*gps["estimate"][:, :2].T, "--", label="wheel odometry")
    right.plot(*gps["aligned"][:, :2].T, "-", label="wheel odometry, SE(2)-aligned")
    right.set_aspect("equal", adjustable="datalim")
    right.set(xlabel="east, m", ylabel="north, m", title="Husky: wheel odometry against GPS")
    right.legend(loc="best")
    for ax in (left, right):
        ax.grid(True, alpha=0.3)
    figure.savefig(output, dpi=100)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bags", type=Path, default=BAGS)
    parser.add_argument("--output", type=Path, default=Path("out/figures/ros_bags.png"))
    args = parser.parse_args(argv)
    tb3, gps = turtlebot3(args.bags), husky(args.bags)
    robot = tb3["result"].robot
    print(
        f"TurtleBot3: calibrated radii {robot.left_wheel_radius:.5f}, "
        f"{robot.right_wheel_radius:.5f} m, track {robot.track_width:.4f} m"
    )
    for name, (_, errors) in tb3["runs"].items():
        print(
            f"  {name:10} against /odom: max {errors.max_position:.3f} m, final "
            f"{errors.final_position:.3f} m, max heading {errors.max_heading:.1f} deg"
        )
    print(
        f"Husky: {gps['travelled']:.0f} m of wheel odometry against {len(gps['truth'])} GPS "
        f"fixes: ATE {gps['ate']:.2f} m raw, {gps['ate_aligned']:.2f} m SE(2)-aligned"
    )
    args.output.parent.mkdir(parents=True, exist_ok=True)
    draw(tb3, gps, args.output)
    print(f"figure: {args.output}")


if __name__ == "__main__":
    main()
