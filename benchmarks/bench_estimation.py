"""Fusing late vision with wheels and a gyro: diffdrive's PoseEstimator against robotpy-wpimath's
DifferentialDrivePoseEstimator, side by side on the same data in one run.

Accuracy. The scenario of WPILib's own estimator test: a figure-eight through five waypoints
(wpimath's TrajectoryGenerator, 2 m/s, 2 m/s^2), a 1 m track, 0.02 s steps, a gyro angle with
white noise of 0.05 rad, vision poses at 10 Hz with noise 0.1 m, 0.1 m, 0.05 rad arriving
0.25 s late. Unlike WPILib's test, each sensor is stamped at its own time (there, the wheel
distances run one step ahead of the truth) and the wheels have noise: the variance of each
wheel's travel is k |travel| (k = 2e-5 m; noisier wheels: 2e-4 m, and 1e-3 m). Another
variant has two cameras whose latencies cross (0.05 s and 0.30 s). wpimath's estimator runs
with the standard deviations of its test (state 0.02, 0.02, 0.01; vision 0.1, 0.1, 0.1);
diffdrive's with the sensors' own (the wheels' k, the gyro's 0.05 rad as a heading
measurement at every step, the vision's sigma). Per seed: the mean and the maximum
translation error over the steps; printed: their medians over the seeds (120: the median of
30 seeds moves by several points from one set of 30 to the next, so each 30 in turn is
printed too), and the share of steps at which the truth lies inside diffdrive's 95 % position
ellipse, pooled.

Speed. One wheel+gyro update at 200 Hz, and one vision measurement 0.25 s late (50 wheel
intervals back), each called from Python, medians of rounds; the late pose also as a NumPy
array and as lists, against the target of the same cost (within 10 %) whatever its type.

    pip install -e '.[bench]'
    python benchmarks/bench_estimation.py [--seeds 120] [--coverage-seeds 100]
"""

from __future__ import annotations

import argparse
import math
import platform

import numpy as np

import diffdrive as dd
from diffdrive import batch
from diffdrive.estimation import EstimatorSettings, PoseEstimator
from timing import per_call  # benchmarks/timing.py

DT = 0.02
TRACK = 1.0
RADIUS = 0.1
ROBOT = dd.DiffDrive(wheel_radius=RADIUS, track_width=TRACK)
GYRO_SIGMA = 0.05
VISION_SIGMA = (0.1, 0.1, 0.05)
VARIANTS = {
    "WPILib's test (one camera, 0.25 s late)": dict(k=2e-5, latencies=(0.25,)),
    "noisier wheels (k 10 times)": dict(k=2e-4, latencies=(0.25,)),
    "two cameras, 0.05 s and 0.30 s late": dict(k=2e-5, latencies=(0.05, 0.30)),
    # Past the variants: wheels so noisy that the vision alone bounds the error.
    "much noisier wheels (k 50 times)": dict(k=1e-3, latencies=(0.25,)),
}


def figure_eight():
    """The times, true poses ``(N, 3)`` and true wheel-angle increments ``(N-1, 2)`` of the
    figure-eight: wpimath's trajectory sampled every 0.02 s, each step's arc (forward travel
    and turn between samples) driven by the wheels, so the truth is the exact step's."""
    from wpimath import geometry, trajectory

    waypoints = [
        geometry.Pose2d(0, 0, geometry.Rotation2d.fromDegrees(45)),
        geometry.Pose2d(3, 0, geometry.Rotation2d.fromDegrees(-90)),
        geometry.Pose2d(0, 0, geometry.Rotation2d.fromDegrees(135)),
        geometry.Pose2d(-3, 0, geometry.Rotation2d.fromDegrees(-90)),
        geometry.Pose2d(0, 0, geometry.Rotation2d.fromDegrees(45)),
    ]
    path = trajectory.TrajectoryGenerator.generateTrajectory(
        waypoints, trajectory.TrajectoryConfig(2, 2)
    )
    times = np.arange(0.0, path.totalTime(), DT)
    sampled = np.array(
        [[s.pose.X(), s.pose.Y(), s.pose.rotation().radians()] for s in map(path.sample, times)]
    )
    sampled[:, 2] = np.unwrap(sampled[:, 2])
    arcs = batch.log(batch.relative_to(sampled[1:], sampled[:-1]))
    forward, turn = arcs[:, 0], arcs[:, 2]
    increments = np.stack([forward - 0.5 * TRACK * turn, forward + 0.5 * TRACK * turn], -1) / RADIUS
    truth = dd.simulate(ROBOT, increments / DT, times=times, initial_pose=sampled[0]).poses
    return times, truth, increments


def sensors(rng, times, truth, increments, k, latencies):
    """Noisy wheel increments, gyro angles and the vision queue ``(arrival, stamp, pose)``."""
    travel = np.abs(increments * RADIUS)
    wheels = increments + rng.normal(size=increments.shape) * np.sqrt(k * travel) / RADIUS
    gyro = truth[:, 2] + rng.normal(size=len(times)) * GYRO_SIGMA
    queue = []
    for camera, latency in enumerate(latencies):
        for step in range(0, len(times), 5):  # 10 Hz
            stamp = times[step] + 0.003 * camera
            stamp = min(stamp, times[-1])
            pose = dd.evaluation.interpolate(times, truth, [stamp])[0]
            seen = dd.Pose(*pose).compose(
                dd.Pose(*(rng.normal(size=3) * VISION_SIGMA))  # noise in the robot's frame
            )
            queue.append((stamp + latency, stamp, seen.to_array()))
    queue.sort(key=lambda item: item[0])
    return wheels, gyro, queue


def run_diffdrive(times, truth, wheels, gyro, queue, k, vision=True):
    estimator = PoseEstimator(
        ROBOT,
        EstimatorSettings("wheels", wheel_noise=k),
        initial_pose=dd.Pose(*truth[0]),
        initial_time=times[0],
    )
    estimator.add_heading(times[0], gyro[0], GYRO_SIGMA)
    errors, distances, q = [], [], 0
    for step in range(1, len(times)):
        estimator.update_increments(*wheels[step - 1], times[step])
        estimator.add_heading(times[step], gyro[step], GYRO_SIGMA)
        while vision and q < len(queue) and queue[q][0] <= times[step]:
            estimator.add_pose(queue[q][1], queue[q][2], VISION_SIGMA)
            q += 1
        miss = truth[step, :2] - estimator.state[:2]
        errors.append(math.hypot(*miss))
        distances.append(miss @ np.linalg.solve(estimator.covariance[:2, :2], miss))
    return np.array(errors), np.array(distances)


def run_wpimath(times, truth, wheels, gyro, queue):
    from wpimath import estimator, geometry, kinematics

    filter = estimator.DifferentialDrivePoseEstimator(
        kinematics.DifferentialDriveKinematics(TRACK),
        geometry.Rotation2d(gyro[0]),
        0.0,
        0.0,
        geometry.Pose2d(*truth[0, :2], geometry.Rotation2d(truth[0, 2])),
        (0.02, 0.02, 0.01),
        (0.1, 0.1, 0.1),
    )
    distance = np.concatenate([[[0.0, 0.0]], np.cumsum(wheels * RADIUS, axis=0)])
    errors, q = [], 0
    for step in range(1, len(times)):
        while q < len(queue) and queue[q][0] <= times[step]:
            pose = queue[q][2]
            filter.addVisionMeasurement(
                geometry.Pose2d(pose[0], pose[1], geometry.Rotation2d(pose[2])), queue[q][1]
            )
            q += 1
        estimate = filter.updateWithTime(
            times[step], geometry.Rotation2d(gyro[step]), *distance[step]
        )
        errors.append(math.hypot(truth[step, 0] - estimate.X(), truth[step, 1] - estimate.Y()))
    return np.array(errors)


def accuracy(seeds: int, coverage_seeds: int, block: int = 30) -> None:
    times, truth, increments = figure_eight()
    print(f"figure-eight: {len(times)} steps of {DT} s, {times[-1]:.2f} s; {seeds} seeds\n")
    print(
        "| variant | wpimath mean / max | diffdrive wheels+gyro mean / max | diffdrive fused "
        "mean / max | fused / wpimath (mean, max) | fused / own wheels+gyro (mean) |"
    )
    print("|---|---|---|---|---|---|")
    blocks = {}
    for name, variant in VARIANTS.items():
        rows = {"wpimath": [], "alone": [], "fused": []}
        for seed in range(seeds):
            data = sensors(np.random.default_rng(seed), times, truth, increments, **variant)
            rows["wpimath"].append(run_wpimath(times, truth, *data))
            rows["alone"].append(run_diffdrive(times, truth, *data, variant["k"], False)[0])
            rows["fused"].append(run_diffdrive(times, truth, *data, variant["k"])[0])
        means = {key: np.array([e.mean() for e in runs]) for key, runs in rows.items()}
        peaks = {key: np.array([e.max() for e in runs]) for key, runs in rows.items()}
        med = {key: (np.median(means[key]), np.median(peaks[key])) for key in rows}
        print(
            f"| {name} | {med['wpimath'][0]:.4f} / {med['wpimath'][1]:.4f} m "
            f"| {med['alone'][0]:.4f} / {med['alone'][1]:.4f} m "
            f"| {med['fused'][0]:.4f} / {med['fused'][1]:.4f} m "
            f"| {med['fused'][0] / med['wpimath'][0]:.1%}, "
            f"{med['fused'][1] / med['wpimath'][1]:.1%} "
            f"| {med['fused'][0] / med['alone'][0]:.1%} |"
        )
        # The median of 30 seeds moves by several points from one set of seeds to the next.
        blocks[name] = [
            (
                np.median(means["fused"][s]) / np.median(means["wpimath"][s]),
                np.median(peaks["fused"][s]) / np.median(peaks["wpimath"][s]),
            )
            for s in (slice(lo, lo + block) for lo in range(0, seeds - block + 1, block))
        ]
    print(f"\nfused / wpimath (mean, max) over each {block} seeds in turn:")
    for name, found in blocks.items():
        print(f"  {name}: " + "; ".join(f"{m:.1%}, {x:.1%}" for m, x in found))
    inside = []
    variant = VARIANTS["WPILib's test (one camera, 0.25 s late)"]
    for seed in range(coverage_seeds):
        data = sensors(np.random.default_rng(seed), times, truth, increments, **variant)
        inside.append(run_diffdrive(times, truth, *data, variant["k"])[1] < 5.991)
    share = np.mean(np.concatenate(inside))
    print(
        f"\ntruth inside diffdrive's 95 % position ellipse: {share:.1%} of "
        f"{sum(map(len, inside))} steps over {coverage_seeds} seeds"
    )


def speed(repeats: int) -> None:
    from wpimath import estimator, geometry, kinematics

    rate, n = 200.0, 2000
    dt = 1.0 / rate
    rng = np.random.default_rng(0)
    increments = rng.uniform(0.05, 0.1, (n, 2)).tolist()
    turns = (rng.normal(size=n) * 0.001).tolist()
    distance = np.cumsum(np.array(increments) * RADIUS, axis=0).tolist()
    vision = geometry.Pose2d(0.1, 0.0, geometry.Rotation2d(0.01))

    every = 20  # a measurement 0.25 s late every 0.1 s, while the updates go on
    lag = round(0.25 * rate)

    # the same measurement in the forms a caller has it in: sigmas, a matrix as lists, NumPy
    covariances = {
        "sigmas": (10.0, 10.0, 10.0),
        "lists": (100.0 * np.eye(3)).tolist(),
        "NumPy": 100.0 * np.eye(3),
    }
    poses = {"sigmas": (0.0, 0.0, 0.0), "lists": [0.0, 0.0, 0.0], "NumPy": np.zeros(3)}

    def ours(late: bool, form: str = "sigmas"):
        pose, covariance = poses[form], covariances[form]

        def loop():
            e = PoseEstimator(ROBOT, initial_time=0.0)
            for k in range(n):
                t = (k + 1) * dt
                e.update_increments(increments[k][0], increments[k][1], t, gyro_angle=turns[k])
                if late and k % every == 0 and k > lag:
                    e.add_pose(t - lag * dt, pose, covariance)
            return n

        return loop

    def theirs(late: bool):
        def loop():
            e = estimator.DifferentialDrivePoseEstimator(
                kinematics.DifferentialDriveKinematics(TRACK),
                geometry.Rotation2d(),
                0.0,
                0.0,
                geometry.Pose2d(),
            )
            heading = 0.0
            for k in range(n):
                heading += turns[k]
                t = (k + 1) * dt
                e.updateWithTime(t, geometry.Rotation2d(heading), *distance[k])
                if late and k % every == 0 and k > lag:
                    e.addVisionMeasurement(vision, t - lag * dt)
            return n

        return loop

    medians = per_call(
        {
            "diffdrive": ours(False),
            "wpimath": theirs(False),
            "diffdrive, late": ours(True),
            "wpimath, late": theirs(True),
            "diffdrive, late, lists": ours(True, "lists"),
            "diffdrive, late, NumPy": ours(True, "NumPy"),
        },
        repeats,
    )
    measurements = len([k for k in range(n) if k % every == 0 and k > lag])
    print(f"\nper call, from Python, 200 Hz, median of {repeats} rounds:")
    costs = {}
    for name in ("diffdrive", "wpimath"):
        update = medians[name]
        late = (medians[f"{name}, late"] - update) * n / measurements
        costs[name] = (update, late)
        print(
            f"  {name}: {update * 1e6:.2f} us per wheel+gyro update, {late * 1e6:.2f} us per "
            "measurement 0.25 s late"
        )
    for k, what in enumerate(("update", "late measurement")):
        print(f"  diffdrive / wpimath, {what}: {costs['diffdrive'][k] / costs['wpimath'][k]:.1f}")
    for form in ("lists", "NumPy"):
        late = (medians[f"diffdrive, late, {form}"] - medians["diffdrive"]) * n / measurements
        print(
            f"  diffdrive, a late pose as {form} / as sigmas: {late / costs['diffdrive'][1]:.2f}"
            " (target <= 1.10)"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=120)
    parser.add_argument("--coverage-seeds", type=int, default=100)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    print(f"{platform.processor() or platform.machine()}, Python {platform.python_version()}\n")
    accuracy(args.seeds, args.coverage_seeds)
    speed(args.repeats)


if __name__ == "__main__":
    main()
