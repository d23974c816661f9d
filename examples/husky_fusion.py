"""The real Husky of ``husky_robot_localization_test1.bag`` through ``estimate_trajectory``.

- With no noise figure given: the settings ``estimate_trajectory`` identifies from the log's
  standing stretch, and each heading's error as a filter and smoothed against GPS.
- Heading sources against GPS (positions, SE(2)-aligned ATE): the gyro alone, the wheels and
  the gyro fused, and fused with the wheels' turn scale as a state (this skid-steer robot's
  wheels turn less than it does), the bias from the gyro's mean while the wheels stand still.
- GPS: every other fix fused (the smoother, the start pose fitted to the fixes used) against
  the fixes left out, beside interpolating the fixes used in time, and the wheels' and gyro's
  dead reckoning plus the used fixes' residuals interpolated (the bound of fusing here).
- How honest the gyro estimate's covariance is against the fixes (ANEES and the shares inside
  the 50 % and 95 % ellipses, positions only), and the figure of its errors with their
  2-sigma bands.

The wheel travel and turn of each interval come from the drive controller's odometry, the gyro
from ``/imu/data`` (mounted with its y axis up: roll 90 degrees), the fixes from ``/fix``.

    pip install -e '.[ros]'
    python examples/husky_fusion.py [--bags ../shared/data/ros-bags] [--figure FIGURE.png]
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

import diffdrive as dd
from diffdrive import batch
from diffdrive.estimation import (
    Gyro,
    GyroNoise,
    estimate_trajectory,
    measurements_of,
    rotation_from_rpy,
)
from diffdrive.estimation.gyro import stationary_bias
from diffdrive.evaluation import align, ate, interpolate
from diffdrive.io import ros

BAGS = Path(__file__).resolve().parents[2] / "shared" / "data" / "ros-bags"
# A Husky's nominal geometry: 0.165 m wheels, 0.555 m between the wheel centres.
HUSKY = dd.DiffDrive(wheel_radius=0.165, track_width=0.555)


def read(bags: Path) -> dict:
    """The wheel increments, gyro and fixes of the bag, over the span the gyro covers."""
    bag = bags / "husky_robot_localization_test1.bag"
    odometry = ros.read_odometry(bag, "/husky_velocity_controller/odom")
    imu = ros.read_imu(bag, "/imu/data")
    gps = ros.read_navsatfix(bag, "/fix")
    gyro = Gyro.from_imu(imu.times, imu.angular_velocity, rotation_from_rpy(math.pi / 2, 0, 0))
    inside = (odometry.times >= gyro.times[0]) & (odometry.times <= gyro.times[-1])
    times, poses = odometry.times[inside], odometry.poses[inside]
    motion = batch.log(batch.relative_to(poses[1:], poses[:-1]))
    arcs = motion[:, :1] + 0.5 * HUSKY.track_width * motion[:, 2:] * np.array([-1.0, 1.0])
    increments = arcs / np.array([HUSKY.left_wheel_radius, HUSKY.right_wheel_radius])
    fixes = (gps.times >= times[0]) & (gps.times <= times[-1])
    bias = stationary_bias(times, increments, np.diff(gyro.angles(times)))
    return {
        "times": times,
        "start": poses[0],
        "increments": increments,
        "gyro": gyro,
        "bias": bias,
        "fix_times": gps.times[fixes],
        "fixes": gps.positions[fixes],
        "sigma": float(np.sqrt(np.median(gps.variance[fixes]))),
        "variance": gps.variance[fixes],
    }


def against_gps(data: dict, estimate) -> float:
    """SE(2)-aligned ATE of the estimate's positions at the fixes, m."""
    at = interpolate(data["times"], estimate.poses, data["fix_times"])
    at[:, 2] = 0.0
    truth = np.column_stack([data["fixes"], np.zeros(len(data["fixes"]))])
    return ate(at, truth, aligned=True)


def heading_sources(data: dict) -> dict:
    common = dict(gyro=data["gyro"], initial_pose=data["start"], smooth=False, bias=data["bias"])
    common.update(wheel_noise=1e-3)
    runs = {
        "gyro": estimate_trajectory(
            HUSKY, data["times"], data["increments"], heading="gyro", **common
        ),
        "fused": estimate_trajectory(
            HUSKY, data["times"], data["increments"], heading="fused", **common
        ),
        "fused, turn scale": estimate_trajectory(
            HUSKY,
            data["times"],
            data["increments"],
            heading="fused",
            turn_scale_sigma=0.1,
            **common,
        ),
    }
    return {name: (against_gps(data, run), run.states[-1, 4]) for name, run in runs.items()}


def no_setting_given(data: dict) -> dict:
    """SE(2)-aligned ATE (m) of each heading as a filter and smoothed, with no noise figure
    and no bias given: what ``estimate_trajectory`` identifies from the log's standing
    stretches (its ``settings``), the library's default wheel noise."""
    errors, settings = {}, ()
    for heading in ("wheels", "gyro", "fused"):
        for smooth in (False, True):
            run = estimate_trajectory(
                HUSKY, data["times"], data["increments"], gyro=data["gyro"], heading=heading,
                initial_pose=data["start"], smooth=smooth,
            )  # fmt: skip
            errors[heading, smooth] = against_gps(data, run)
            settings = run.settings
    return {"errors": errors, "settings": settings}


def every_other_fix(data: dict, k: float = 0.3, sigma: float = 0.2) -> dict:
    """Mean distance (m) to the fixes left out: interpolating the fixes used, and the smoothed
    estimate with them (wheels' ``k`` m, fixes taken with ``sigma`` m)."""
    stamps, fixes = data["fix_times"], data["fixes"]
    used = np.arange(len(stamps)) % 2 == 0
    left = ~used
    between = np.column_stack(
        [np.interp(stamps[left], stamps[used], fixes[used, i]) for i in (0, 1)]
    )
    options = dict(gyro=data["gyro"], heading="fused", bias=data["bias"], wheel_noise=k)
    options["noise"] = GyroNoise(
        angle_random_walk=0.01, rate_random_walk=1e-4, initial_bias_sigma=1e-3
    )
    dead = estimate_trajectory(
        HUSKY,
        data["times"],
        data["increments"],
        smooth=False,
        initial_pose=data["start"],
        **options,
    )
    path = interpolate(data["times"], dead.poses, stamps[used])
    flat = np.column_stack([path[:, :2], np.zeros(len(path))])
    fitted = align(flat, np.column_stack([fixes[used], np.zeros(len(path))]))
    moved = batch.compose(fitted[0], batch.inverse(flat[0]))
    start = batch.compose(moved, data["start"])
    measurements = measurements_of("position", stamps[used], fixes[used], sigma)
    smoothed = estimate_trajectory(
        HUSKY,
        data["times"],
        data["increments"],
        measurements=measurements,
        initial_pose=start,
        initial_covariance=np.diag([1.0, 1.0, 0.05]),
        gate=1 - 1e-9,
        **options,
    )
    at = interpolate(data["times"], smoothed.poses, stamps[left])
    # The most a fused estimate could take from the wheels here: between fixes, their motion;
    # the fixes' own error, interpolated (a GPS error state with no white noise of its own).
    carried = interpolate(data["times"], dead.poses, stamps)[:, :2]
    residual = np.column_stack(
        [np.interp(stamps[left], stamps[used], (fixes - carried)[used, i]) for i in (0, 1)]
    )
    return {
        "interpolated": float(np.mean(np.hypot(*(between - fixes[left]).T))),
        "residuals": float(np.mean(np.hypot(*(carried[left] + residual - fixes[left]).T))),
        "smoothed": float(np.mean(np.hypot(*(at[:, :2] - fixes[left]).T))),
        "refused": smoothed.rejected,
        "used": int(used.sum()),
    }


def consistency_against_gps(data: dict, figure: Path, k: float = 1e-3) -> dict:
    """How honest the gyro estimate's covariance is against the fixes: wheels ``k`` m and the
    gyro (its heading), the estimate moved onto the fixes by the rigid motion that best fits
    them, its covariance turned with it and each fix's reported variance added (the
    reference's own noise, as ``noise.covariances`` adds it). ``figure``: the x and y errors
    with their 2-sigma bands."""
    from diffdrive.evaluation import consistency
    from diffdrive.plot import plot_error_bands

    estimate = estimate_trajectory(
        HUSKY, data["times"], data["increments"], heading="gyro", gyro=data["gyro"],
        initial_pose=data["start"], smooth=False, bias=data["bias"], wheel_noise=k,
    )  # fmt: skip
    stamps = data["fix_times"]
    at = interpolate(data["times"], estimate.poses, stamps)
    nearest = np.clip(np.searchsorted(data["times"], stamps), 0, len(data["times"]) - 1)
    flat = np.column_stack([at[:, :2], np.zeros(len(at))])
    moved = align(flat, np.column_stack([data["fixes"], np.zeros(len(at))]))
    c, s = math.cos(moved[0, 2]), math.sin(moved[0, 2])  # the rotation align applied
    turn = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    covariances = turn @ estimate.covariances[nearest] @ turn.T
    covariances[:, 0, 0] += data["variance"]
    covariances[:, 1, 1] += data["variance"]
    truth = np.column_stack([data["fixes"], np.full(len(at), np.nan)])
    found = consistency(moved, covariances, truth)
    figure.parent.mkdir(parents=True, exist_ok=True)
    title = "Husky against GPS: wheels and gyro, the estimate aligned to the fixes"
    plot_error_bands(stamps - stamps[0], moved, covariances, truth, figure, title)
    return {"anees": found.anees, "inside_95": found.inside_95, "inside_50": found.inside_50}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bags", type=Path, default=BAGS)
    parser.add_argument("--figure", type=Path, default=Path("out/figures/noise_husky.png"))
    args = parser.parse_args(argv)
    data = read(args.bags)
    found = heading_sources(data)
    print(
        "Husky against GPS, SE(2)-aligned ATE: "
        + ", ".join(f"{name} {error:.2f} m" for name, (error, _) in found.items())
        + f"; turn scale learnt {found['fused, turn scale'][1]:.3f}"
    )
    plain = no_setting_given(data)
    for line in plain["settings"]:
        print(f"  {line}")
    e = plain["errors"]
    best = min(e["gyro", False], e["wheels", False])
    print(
        f"no setting given: fused {e['fused', False]:.3f} m as a filter "
        f"({100 * (e['fused', False] / best - 1):+.1f} % against the better dead reckoning, "
        f"gyro {e['gyro', False]:.3f} m, wheels {e['wheels', False]:.3f} m), "
        f"{e['fused', True]:.3f} m smoothed "
        f"({100 * (e['fused', True] / min(e['gyro', True], e['wheels', True]) - 1):+.1f} %)"
    )
    gps = every_other_fix(data)
    print(
        f"every other fix ({gps['used']} used, reported sigma {data['sigma']:.2f} m): mean "
        f"distance to the fixes left out {gps['interpolated']:.3f} m interpolating the used "
        f"ones, {gps['smoothed']:.2f} m smoothed ({gps['refused']} refused by the gate), "
        f"{gps['residuals']:.3f} m dead reckoning plus the used fixes' residuals interpolated"
    )

    honest = consistency_against_gps(data, args.figure)
    print(
        f"the gyro estimate's covariance against GPS (with each fix's reported variance): "
        f"ANEES {honest['anees']:.2f}, {honest['inside_95']:.0%} inside the 95 % ellipse, "
        f"{honest['inside_50']:.0%} inside the 50 % one; figure: {args.figure}"
    )


if __name__ == "__main__":
    main()
