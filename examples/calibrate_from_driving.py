"""Calibration from ordinary driving: the Husky bag's wheels, GPS and gyro, no motion capture.

``diffdrive.calibration.calibrate_to_reference`` on the wheels of
``../shared/data/ros-bags/husky_robot_localization_test1.bag`` (from its ``/odom``, 10 Hz),
its ``/fix`` positions and its IMU's yaw rate (30 Hz), no noise figure given: the wheels' and
the fixes' noise identified from the drive (``identify_noise``), the gyro's from the log's
standing stretch; the fixes' clock held (at the limit of what the drive determines), and
what else the log does not determine (``UndeterminedError``) left out, and why. It prints the
calibration's report, the gyro's clock against the wheels, the estimator's settings the
calibration gives in one call (``estimator_settings``: the wheels' scales, the gyro's bias,
clock and scale, the antenna's lever arm), and the gyro-heading dead reckoning's SE(2)-aligned
ATE against the fixes (m) with the nominal wheels, the calibrated ones, and the nominal ones
with the estimator started from the calibration, all over the same span.

    python examples/calibrate_from_driving.py [--bags ../shared/data/ros-bags]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import diffdrive as dd
from diffdrive.calibration.reference import (
    ReferenceSettings,
    UndeterminedError,
    calibrate_to_reference,
    estimable,
)
from diffdrive.estimation import EstimatorSettings, estimate_trajectory
from diffdrive.estimation.standing import warm_up
from diffdrive.sensor_noise import DEFAULT

sys_path = Path(__file__).resolve().parent
BAGS = sys_path.parents[1] / "shared" / "data" / "ros-bags"
NOISE = ("wheels", "reference")  # identified; the gyro's is the standing stretch's
HELD = "its standard error here sits at the limit past which a parameter is left out"


def calibrated(data: dict):
    """The calibration against the fixes, the noise of the wheels and the fixes identified
    from the log and the gyro's from its standing stretch; what the log does not determine
    left out, with the reason. The calibration, the standing stretch and the lines on what
    was left out."""
    from husky_fusion import HUSKY

    standing = warm_up(data["times"], data["increments"], data["gyro"])
    if standing is None:
        raise ValueError("the log has no standing stretch to identify the gyro's noise from")
    common = dict(gyro=data["gyro"], gyro_noise=standing.noise)
    start = dict(sigma=data["sigma"], wheel_noise=DEFAULT)
    args = (HUSKY, data["times"], data["increments"], data["fix_times"], data["fixes"])
    # The fixes' clock sits at the limit of what this drive determines (a standard error of
    # about 0.2 s, the limit past which a parameter is refused): which side a run falls on
    # moved with the processor's rounding, so it is held, as calibrate-driving --hold offset.
    estimate = tuple(name for name in estimable(poses=False, gyro=True) if name != "offset")
    left_out = [f"held offset at 0 s: {HELD}"]
    while True:
        try:
            settings = ReferenceSettings(estimate=estimate, identify_noise=NOISE)
            found = calibrate_to_reference(*args, **common, **start, settings=settings)
            return found, standing, left_out
        except UndeterminedError as refused:
            left_out.append(f"left out {', '.join(refused.parameters)}: {refused}")
            estimate = tuple(name for name in estimate if name not in refused.parameters)
            if refused.noise is not None:  # the next try starts from the noise found
                found_noise = refused.noise.values
                start = dict(sigma=found_noise["reference"], wheel_noise=found_noise["wheels"])


def dead_reckoning_ate(
    data: dict, robot: dd.DiffDrive, span, settings: EstimatorSettings | None = None
) -> float:
    """The gyro-heading dead reckoning's SE(2)-aligned ATE against the fixes inside ``span``
    (the wheel indices ``first, last``), m; ``settings``: the estimator's, its heading made
    the gyro's."""
    from husky_fusion import against_gps

    first, last = span
    times = data["times"][first : last + 1]
    settings = (settings or EstimatorSettings()).replace(heading="gyro")
    run = estimate_trajectory(
        robot, times, data["increments"][first:last], gyro=data["gyro"], settings=settings,
        initial_pose=data["start"], smooth=False,
    )  # fmt: skip
    inside = (data["fix_times"] >= times[0]) & (data["fix_times"] <= times[-1])
    part = {"times": times, "fix_times": data["fix_times"][inside], "fixes": data["fixes"][inside]}
    return against_gps(part, run)


def main(argv: list[str] | None = None) -> None:
    import sys

    sys.path.insert(0, str(sys_path))
    from husky_fusion import HUSKY, read

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bags", type=Path, default=BAGS)
    args = parser.parse_args(argv)
    data = read(args.bags)
    found, standing, left_out = calibrated(data)
    for line in standing.report:
        print(f"gyro, from the standing stretch: {line}")
    for line in left_out:
        print(line)
    print(f"calibration (chi-square per degree of freedom {found.chi2:.2f}):")
    for line in found.report:
        print(f"  {line}")
    offset, offset_error = found.value("gyro_offset"), found.standard_errors()["gyro_offset"]
    print(f"gyro clock against the wheels {offset:.3f} +- {offset_error:.3f} s")
    # The span the gyro covers once on the wheels' clock, for every run alike.
    shifted = data["gyro"].calibrated(offset)
    kept = np.flatnonzero(
        (data["times"] >= shifted.times[0]) & (data["times"] <= shifted.times[-1])
    )
    span = (int(kept[0]), int(kept[-1]))
    nominal = dead_reckoning_ate(data, HUSKY, span)
    scaled = dead_reckoning_ate(data, found.robot, span)
    # The whole calibration in the estimator's settings, the nominal robot given.
    started = found.estimator_settings(HUSKY)
    sensors = started.sensors
    print(
        f"the estimator's settings from it (one call), for the nominal robot: distance scale "
        f"{started.distance.start:.4f} +- {started.distance.sigma:.4f}, turn scale "
        f"{started.turn_scale.start:.4f} +- {started.turn_scale.sigma:.4f}, bias "
        f"{started.bias_start:.3g} rad/s, gyro clock {sensors.gyro_offset:.3f} s and scale "
        f"{sensors.gyro_scale:.4f}, lever arm ({sensors.lever_arm[0]:.3f}, "
        f"{sensors.lever_arm[1]:.3f}) m"
    )
    timed = dead_reckoning_ate(data, HUSKY, span, started)
    print(f"gyro-heading ATE: nominal wheels {nominal:.3f} m, calibrated wheels {scaled:.3f} m, "
          f"and the estimator started from the calibration {timed:.3f} m (target at most "
          "2.62 m)")  # fmt: skip


if __name__ == "__main__":
    main()
