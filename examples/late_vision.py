"""Wheels, a gyro and a camera whose poses arrive 0.25 s late, through ``PoseEstimator``.

Two loops, one each way (1.5 m/s, a 1 m track, 50 Hz): wheel angles with random-walk noise
(``k = 2e-5`` m, from ``diffdrive.sensors``), a gyro angle with white noise of 0.05 rad at every
step (applied as a heading measurement), and camera poses at 10 Hz with noise 0.1 m, 0.1 m,
0.05 rad that arrive 0.25 s after they were taken (``sensors.absolute_readings``). The
estimator applies each pose at its stamp and replays the wheels since. Printed, as medians
over ``--seeds`` runs: the mean and largest position error with and without the camera, and
the share of steps at which the truth lies inside the 95 % position ellipse (pooled); drawn:
the first run's truth, estimate, camera poses and a few ellipses.

    pip install -e '.[plot]'
    python examples/late_vision.py [--seeds 10] [--output FIGURE.png]
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

import diffdrive as dd
from diffdrive import sensors
from diffdrive.estimation import EstimatorSettings, PoseEstimator

ROBOT = dd.DiffDrive(wheel_radius=0.1, track_width=1.0)
DT, K, GYRO_SIGMA, CAMERA_SIGMA = 0.02, 2e-5, 0.05, (0.1, 0.1, 0.05)


def figure_eight() -> tuple[np.ndarray, np.ndarray]:
    """Times ``(N,)`` and true poses ``(N, 3)``: two loops at 1.5 m/s, the turn rate swinging
    one way, then the other."""
    times = np.arange(0.0, 12.0 + 1e-9, DT)
    speed, turn = 1.5, 2.4 * np.sin(2 * np.pi * times[:-1] / 12.0)
    wheels = np.stack([speed - 0.5 * turn, speed + 0.5 * turn], axis=-1) / 0.1
    return times, dd.simulate(ROBOT, wheels, times=times).poses


def run(seed: int, camera: bool = True) -> dict:
    """One streamed run: the truth, the estimates and covariances at every step, the camera."""
    times, truth = figure_eight()
    encoders = sensors.encoder_readings(
        ROBOT, times, truth, sensors.EncoderModel(wheel_noise=K), seed=seed
    )
    wheels = encoders.readings[0]  # wheel angles, rad
    poses = sensors.absolute_readings(
        ROBOT,
        times,
        truth,
        sensors.AbsoluteModel(CAMERA_SIGMA, period=0.1, latency=0.25),
        seed=seed + 1,
    )
    yaw = truth[:, 2] + np.random.default_rng(seed + 2).normal(size=len(times)) * GYRO_SIGMA
    order = np.argsort(poses.arrival, kind="stable")
    settings = EstimatorSettings("wheels", wheel_noise=K)
    estimator = PoseEstimator(ROBOT, settings, initial_pose=dd.Pose(*truth[0]))
    estimator.update_positions(*wheels[0], times[0])
    estimates, covariances, next_pose = [truth[0]], [np.zeros((3, 3))], 0
    for step in range(1, len(times)):
        estimator.update_positions(*wheels[step], times[step])
        estimator.add_heading(times[step], yaw[step], GYRO_SIGMA)
        while camera and next_pose < len(order) and poses.arrival[order[next_pose]] <= times[step]:
            k = order[next_pose]
            estimator.add_pose(poses.times[k], poses.poses[0, k], CAMERA_SIGMA)
            next_pose += 1
        estimates.append(estimator.pose.to_array())
        covariances.append(estimator.covariance)
    return {
        "truth": truth,
        "estimates": np.array(estimates),
        "covariances": np.array(covariances),
        "camera": poses.poses[0],
        "rejected": estimator.rejected,
    }


def errors(result: dict) -> tuple[float, float, float]:
    """Mean and largest position error (m), and the share of steps inside the 95 % ellipse."""
    miss = (result["truth"] - result["estimates"])[1:, :2]
    inverse = np.linalg.inv(result["covariances"][1:, :2, :2])
    inside = np.einsum("ni,nij,nj->n", miss, inverse, miss) < 5.991
    distance = np.hypot(*miss.T)
    return float(distance.mean()), float(distance.max()), float(inside.mean())


def draw(result: dict, output: Path) -> None:
    from matplotlib.figure import Figure
    from matplotlib.patches import Ellipse

    figure = Figure(figsize=(9, 5), layout="constrained")
    ax = figure.subplots()
    truth, estimates = result["truth"], result["estimates"]
    ax.plot(*truth[:, :2].T, color="0.6", linewidth=3, label="truth")
    ax.plot(
        *result["camera"][:, :2].T,
        ".",
        color="tab:orange",
        markersize=4,
        label="camera poses (0.25 s late)",
    )
    ax.plot(*estimates[:, :2].T, color="tab:blue", linewidth=1, label="estimate")
    for k in range(25, len(estimates), 50):  # the 95 % ellipse, magnified 10 times
        values, vectors = np.linalg.eigh(result["covariances"][k, :2, :2])
        width, height = 2 * np.sqrt(5.991 * values) * 10
        angle = math.degrees(math.atan2(vectors[1, 1], vectors[0, 1]))
        ax.add_patch(
            Ellipse(
                estimates[k, :2],
                height,
                width,
                angle=angle,
                fill=False,
                color="tab:blue",
                alpha=0.7,
            )
        )
    ax.plot([], [], color="tab:blue", alpha=0.7, label="95 % ellipse, x10")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set(xlabel="x, m", ylabel="y, m", title="wheels, gyro and a late camera: PoseEstimator")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best")
    figure.savefig(output, dpi=100)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--output", type=Path, default=Path("out/figures/late_vision.png"))
    args = parser.parse_args(argv)
    runs = {
        "wheels and gyro": [run(seed, camera=False) for seed in range(args.seeds)],
        "with the camera": [run(seed) for seed in range(args.seeds)],
    }
    for name, results in runs.items():
        found = np.array([errors(result) for result in results])
        mean, largest, _ = np.median(found, axis=0)
        print(
            f"{name}: mean position error {mean:.4f} m, largest {largest:.4f} m (medians of "
            f"{args.seeds} runs); truth inside the 95 % ellipse at {found[:, 2].mean():.1%} "
            "of steps"
        )
    refused = sum(result["rejected"] for result in runs["with the camera"])
    print(f"camera poses refused by the gate: {refused}")
    args.output.parent.mkdir(parents=True, exist_ok=True)
    draw(runs["with the camera"][0], args.output)
    print(f"figure: {args.output}")


if __name__ == "__main__":
    main()
