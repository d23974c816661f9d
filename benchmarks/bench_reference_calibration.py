"""Calibration against a reference that is not ground truth, on synthetic drives of known
parameters (``tests/reference_drive.py``): how often each parameter lands within its target
and within two of its reported standard errors, against the Cramer-Rao bound, and what a
calibration costs.

Per seed: a 5-minute mixed drive (straights, arcs and turns in place both ways) at 100 Hz,
wheels with a random walk of 1e-5 m, and either

- a camera at 10 Hz with 2 cm and 1 degree of noise, mounted at (0.15, -0.05) m and 0.1 rad,
  its clock 50 ms ahead; or
- a GPS receiver at 2 Hz with 0.5 m of noise, its antenna at (-0.2, 0.1) m, its clock 0.3 s
  ahead, and a gyro of 2e-3 rad/s/sqrt(Hz) with a 1 % scale error, a bias of 5e-3 rad/s and
  its clock 20 ms ahead.

``calibration.calibrate_to_reference`` starts from the nominal robot. The Cramer-Rao bound
is the inverse of the information at the true parameters under the true noise: the least
standard error an unbiased calibration of that drive can have (the model's, which leaves out
the gyro heading's own random walk). Last, one 10-minute log at 100 Hz with each reference,
timed (median of 3). Then the noise identified from the log (``identify_noise``): a camera
at 10 Hz and a gyro, every figure started 2-10 times off; each term and each parameter under
it against the truth, and a 10-minute log's time. Last, the track beside a gyro with wheels of
random walk 1e-7, 1e-5 and 4e-5 m: its error in standard errors, with the wheels-against-gyro
weights moving with the track and, side by side, held.

    python benchmarks/bench_reference_calibration.py [--seeds 100] [--noise-seeds 40]
        [--track-seeds 40] [--log-seconds 600] [--repeats 3]
"""

from __future__ import annotations

import argparse
import platform
import sys
from pathlib import Path

import numpy as np

from diffdrive.calibration import reference
from diffdrive.sensor_noise import GyroNoise

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import reference_drive as scenario  # the tests' scenario
from timing import median_time  # benchmarks/timing.py

GEOMETRY = {
    "left_radius": scenario.TRUE.left_wheel_radius,
    "right_radius": scenario.TRUE.right_wheel_radius,
    "track": scenario.TRUE.track_width,
}
CAMERA_TRUTH = {
    **GEOMETRY,
    "lever_x": scenario.MOUNT[0],
    "lever_y": scenario.MOUNT[1],
    "yaw": scenario.MOUNT[2],
    "offset": scenario.CLOCK,
}
GPS_TRUTH = {
    **GEOMETRY,
    "lever_x": scenario.ANTENNA[0],
    "lever_y": scenario.ANTENNA[1],
    "offset": scenario.GPS_CLOCK,
    "gyro_scale": scenario.GYRO["scale"],
    "gyro_bias": scenario.GYRO["bias"],
    "gyro_offset": scenario.GYRO["clock"],
}
# Each parameter's target, and how its error is shown: (target, scale to the unit, unit).
CAMERA_TARGETS = {
    "left_radius": (0.001, 100, "%"),
    "right_radius": (0.001, 100, "%"),
    "track": (0.0015, 100, "%"),
    "lever_x": (0.005, 1000, "mm"),
    "lever_y": (0.005, 1000, "mm"),
    "yaw": (np.radians(0.2), 180 / np.pi, "deg"),
    "offset": (0.002, 1000, "ms"),
}
GPS_TARGETS = {
    "left_radius": (0.006, 100, "%"),
    "right_radius": (0.006, 100, "%"),
    "track": (0.006, 100, "%"),
    "lever_x": (0.08, 1000, "mm"),
    "lever_y": (0.08, 1000, "mm"),
    "offset": (0.2, 1000, "ms"),
    "gyro_scale": (np.nan, 100, "%"),
    "gyro_bias": (np.nan, 1000, "mrad/s"),
    "gyro_offset": (0.005, 1000, "ms"),
}


def _calibrate(robot, data, gps: bool, settings: reference.ReferenceSettings | None = None):
    if gps:
        times, increments, gyro, stamps, positions = data
        return reference.calibrate_to_reference(
            robot, times, increments, stamps, positions, sigma=scenario.GPS_SIGMA, gyro=gyro,
            gyro_noise=GyroNoise(angle_random_walk=scenario.GYRO_ARW), wheel_noise=scenario.K,
            settings=settings,
        )  # fmt: skip
    times, increments, stamps, poses = data
    return reference.calibrate_to_reference(
        robot, times, increments, stamps, poses, sigma=scenario.CAMERA, wheel_noise=scenario.K,
        settings=settings,
    )  # fmt: skip


def one_seed(seed: int, gps: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The errors (relative for the geometry), the reported standard errors and the
    Cramer-Rao bound, each ``(P,)`` over the scenario's parameters."""
    truth = GPS_TRUTH if gps else CAMERA_TRUTH
    data = scenario.gps_drive(seed) if gps else scenario.drive(seed)
    found = _calibrate(scenario.NOMINAL, data, gps)
    at_truth = {name: value for name, value in truth.items() if name not in GEOMETRY}
    if gps:
        at_truth["heading"] = found.value("heading")
    at_truth_once = reference.ReferenceSettings(initial=at_truth, iterations=1)
    bound = _calibrate(scenario.TRUE, data, gps, at_truth_once)
    names = list(truth)
    size = np.array([truth[n] if n in GEOMETRY else 1.0 for n in names])
    errors = np.array([found.value(n) - truth[n] for n in names]) / size
    reported = np.array([found.standard_errors()[n] for n in names]) / size
    spread = np.sqrt(np.diag(np.linalg.pinv(bound.information)))
    crb = np.array([spread[bound.estimated.index(n)] for n in names]) / size
    return errors, reported, crb


def table(gps: bool, seeds: int, seconds: float = 600.0, repeats: int = 3) -> None:
    targets = GPS_TARGETS if gps else CAMERA_TARGETS
    results = [one_seed(seed, gps) for seed in range(seeds)]
    errors = np.abs(np.array([e for e, _, _ in results]))
    reported = np.array([r for _, r, _ in results])
    crb = np.array([c for _, _, c in results])
    print(f"\n{'GPS at 2 Hz and a gyro' if gps else 'camera at 10 Hz'}, {seeds} seeds:\n")
    print("| parameter | target | within target | within 2 SE | median error | median SE | "
          "Cramer-Rao bound |")  # fmt: skip
    print("|---|---|---|---|---|---|---|")
    for index, (name, (target, scale, unit)) in enumerate(targets.items()):
        within = f"{np.mean(errors[:, index] <= target):.0%}" if np.isfinite(target) else "-"
        shown = f"{target * scale:.3g} {unit}" if np.isfinite(target) else "-"
        honest = np.mean(errors[:, index] <= 2 * reported[:, index])
        print(
            f"| {name} | {shown} | {within} | {honest:.0%}"
            f" | {np.median(errors[:, index]) * scale:.3g} {unit} | "
            f"{np.median(reported[:, index]) * scale:.3g} {unit} | "
            f"{np.median(crb[:, index]) * scale:.3g} {unit} |"
        )
    data = (scenario.gps_drive if gps else scenario.drive)(0, seconds=seconds)
    spent = median_time(lambda: _calibrate(scenario.NOMINAL, data, gps), repeats)
    print(f"\na {seconds / 60:g}-minute log at 100 Hz: {spent:.2f} s to calibrate (median of "
          f"{repeats}; target 10 s)")  # fmt: skip


NOISE_TRUTH = {
    "wheels": scenario.K,
    "gyro": scenario.GYRO_ARW,
    "reference": scenario.CAMERA[0],
    "reference_heading": scenario.CAMERA[2],
}


def _identified(data):
    """The camera-and-gyro calibration with every noise figure found from the log, started
    from figures off by 2-10 times."""
    times, increments, stamps, poses, gyro = data
    return reference.calibrate_to_reference(
        scenario.NOMINAL, times, increments, stamps, poses, sigma=(0.04, 0.04, 0.035),
        wheel_noise=1e-4, gyro=gyro, gyro_noise=GyroNoise(angle_random_walk=1e-2),
        settings=reference.ReferenceSettings(identify_noise=True),
    )  # fmt: skip


def noise_table(seeds: int, seconds: float = 600.0, repeats: int = 3) -> None:
    """How often each identified noise figure, and each parameter under it, lies within two
    standard errors of the truth."""
    rows, honest = [], []
    for seed in range(seeds):
        found = _identified(scenario.camera_and_gyro(seed))
        assert found.noise is not None
        rows.append([(found.noise.values[n], found.noise.standard_errors[n]) for n in NOISE_TRUTH])
        spread = found.standard_errors()
        honest.append(
            [abs(found.value(n) - true) <= 2 * spread[n] for n, true in CAMERA_TRUTH.items()]
        )
    table = np.array(rows)  # (seeds, terms, 2)
    print(f"\nthe noise identified from the log (camera at 10 Hz and a gyro), {seeds} seeds:\n")
    print("| term | truth | within 2 SE | median error | median SE |")
    print("|---|---|---|---|---|")
    for index, (name, true) in enumerate(NOISE_TRUTH.items()):
        found, spread = table[:, index, 0], table[:, index, 1]
        within = np.mean(np.abs(found - true) <= 2 * spread)
        error = np.median(np.abs(found / true - 1))
        print(f"| {name} | {true:.3g} | {within:.0%} | {error:.1%} | "
              f"{np.median(spread / true):.1%} |")  # fmt: skip
    inside = np.mean(honest, axis=0)
    print("\nunder the identified noise, each parameter within 2 SE: " + ", ".join(
        f"{name} {share:.0%}" for name, share in zip(CAMERA_TRUTH, inside, strict=True)
    ))  # fmt: skip
    data = scenario.camera_and_gyro(0, seconds=seconds)
    spent = median_time(lambda: _identified(data), repeats)
    print(f"a {seconds / 60:g}-minute log at 100 Hz, camera and gyro, noise identified: "
          f"{spent:.2f} s (median of {repeats})")  # fmt: skip


TRACK_KS = (1e-7, 1e-5, 4e-5)  # m: nearly exact wheels, the scenario's, four times noisier


def _track_z(seed: int, k: float) -> float:
    """The camera-and-gyro drive with wheels of random walk ``k``, calibrated under that
    noise: the track's error in its reported standard errors."""
    scenario.K = k  # the scenario's wheels read it when drawn
    try:
        times, increments, stamps, poses, gyro = scenario.camera_and_gyro(seed)
    finally:
        scenario.K = 1e-5
    found = reference.calibrate_to_reference(
        scenario.NOMINAL, times, increments, stamps, poses, sigma=scenario.CAMERA,
        wheel_noise=k, gyro=gyro, gyro_noise=GyroNoise(angle_random_walk=scenario.GYRO_ARW),
    )  # fmt: skip
    return (found.value("track") - GEOMETRY["track"]) / found.standard_errors()["track"]


def track_table(seeds: int) -> None:
    """The track beside a gyro at each of ``TRACK_KS``: its mean error and how often it lies
    within two standard errors, with the wheels-against-gyro weights moving with the track
    (the fit's) and, side by side, held where they were taken (the errors-in-variables
    bias the fit removes: its variances made constant here)."""
    from diffdrive.calibration import _reference_model as model

    print(f"\nthe track beside a gyro (camera at 10 Hz and a gyro), {seeds} seeds:\n")
    print("| wheels' k | weights | mean error, SE | within 2 SE |")
    print("|---|---|---|---|")
    moving = model.turn_variances
    for k in TRACK_KS:
        for label, variances in (("moving with the track", moving), ("held", None)):
            model.turn_variances = variances or (
                lambda log, values, angles_at=None: np.ones(len(log.stamps) - 1)
            )
            try:
                z = np.array([_track_z(seed, k) for seed in range(seeds)])
            finally:
                model.turn_variances = moving
            print(f"| {k:g} m | {label} | {z.mean():+.2f} | {np.mean(np.abs(z) < 2):.0%} |")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=100)
    parser.add_argument("--noise-seeds", type=int, default=40)
    parser.add_argument("--track-seeds", type=int, default=40)
    parser.add_argument("--log-seconds", type=float, default=600.0, help="the timed logs' length")
    parser.add_argument("--repeats", type=int, default=3, help="timed runs of each log")
    args = parser.parse_args(argv)
    print(f"machine: {platform.machine()}, Python {platform.python_version()}, NumPy "
          f"{np.__version__}")  # fmt: skip
    for gps in (False, True):
        table(gps, args.seeds, args.log_seconds, args.repeats)
    noise_table(args.noise_seeds, args.log_seconds, args.repeats)
    track_table(args.track_seeds)


if __name__ == "__main__":
    main()
