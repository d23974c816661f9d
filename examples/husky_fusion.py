"""The real Husky of ``husky_robot_localization_test1.bag`` through ``estimate_trajectory``,
with no noise figure set by hand: every setting comes from the log.

- The gyro's noise and bias, identified from the log's standing stretches, and each heading's
  error as a filter and smoothed against GPS (positions, SE(2)-aligned ATE).
- GPS across gaps: one fix in every 0.8, 2, 4, 10, 20 and 50 s fused by the smoother with no
  setting given (``WholeLog(fixes="identified")``: the fixes' noise, their offset's wander,
  the wheels' distance scale and the start identified from the used fixes alone,
  ``estimation.fixes``) against the fixes left out, beside interpolating the fixes used in
  time, the dead reckoning plus the used fixes' residuals interpolated, and the smoother with
  the settings identified from the receiver's whole stream.
- The distance scale: the fit's, and the filter's distance-scale state; gyro-heading dead
  reckoning with the wheels so scaled.
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
import dataclasses
import math
from pathlib import Path

import numpy as np

import diffdrive as dd
from diffdrive import batch
from diffdrive.estimation import (
    EstimatorSettings,
    Gyro,
    Prior,
    WholeLog,
    estimate_trajectory,
    identify_fixes,
    measurements_of,
    rotation_from_rpy,
)
from diffdrive.estimation import filter as ekf
from diffdrive.evaluation import align, ate, interpolate, through_fixes
from diffdrive.io import ros

BAGS = Path(__file__).resolve().parents[2] / "shared" / "data" / "ros-bags"
# A Husky's nominal geometry: 0.165 m wheels, 0.555 m between the wheel centres.
HUSKY = dd.DiffDrive(wheel_radius=0.165, track_width=0.555)
# One fix used every this many seconds (the receiver gives one every 0.4 s).
GAPS = (0.8, 2.0, 4.0, 10.0, 20.0, 50.0)
# At this gap the smoother also runs with these white noises of the fixes (m), the rest as
# identified from the used fixes.
SWEPT, WHITES = 10.0, (0.001, 0.1, 0.3, 0.7)


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
    return {
        "times": times,
        "start": poses[0],
        "increments": increments,
        "gyro": gyro,
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


def no_setting_given(data: dict) -> dict:
    """SE(2)-aligned ATE (m) of each heading as a filter and smoothed, with no noise figure
    and no bias given: what ``estimate_trajectory`` identifies from the log's standing
    stretches (its ``settings``), the library's default wheel noise."""
    errors, settings = {}, ()
    for heading in ("wheels", "gyro", "fused"):
        for smooth in (False, True):
            run = estimate_trajectory(
                HUSKY, data["times"], data["increments"], gyro=data["gyro"],
                settings=EstimatorSettings(heading), initial_pose=data["start"], smooth=smooth,
            )  # fmt: skip
            errors[heading, smooth] = against_gps(data, run)
            settings = run.settings
    return {"errors": errors, "settings": settings}


def dead_reckoning(data: dict):
    """The fused heading's filter with no fix and no setting given."""
    return estimate_trajectory(
        HUSKY, data["times"], data["increments"], gyro=data["gyro"], smooth=False
    )


def fix_gaps(data: dict) -> dict:
    """One fix used every ``GAPS`` s, the rest left out: the mean distance (m) to the fixes
    left out of the smoother's fix (its position plus the offset) with no setting given (what
    the fixes are worth identified from the used fixes alone), of interpolating the fixes used
    in time, of the dead reckoning fitted onto the used fixes plus their residuals
    interpolated (the bound of fusing with the wheels trusted between fixes), and of the
    smoother with the settings identified from the receiver's whole stream."""
    stamps, fixes, times = data["fix_times"], data["fixes"], data["times"]
    dead = dead_reckoning(data)
    fit = identify_fixes(times, dead.poses, stamps, fixes, reported=data["sigma"])
    rows = {}
    for gap in GAPS:
        used = np.arange(len(stamps)) % round(gap / 0.4) == 0
        used[-1] = True
        left = ~used
        given = measurements_of("position", stamps[used], fixes[used], data["sigma"])
        plain = EstimatorSettings(whole_log=WholeLog(fixes="identified"))
        smoothed, refused = _smoothed(data, left, given, plain)
        row = {"smoothed": smoothed, "refused": refused, "used": int(used.sum())}
        alone = identify_fixes(times, dead.poses, stamps[used], fixes[used])
        row["white"] = alone.white
        if gap == SWEPT:  # the smoother with the white noise taken otherwise
            row["sweep"] = {
                white: _fitted(data, used, dataclasses.replace(alone, white=white))
                for white in WHITES
            }
        row["whole"] = _fitted(data, used, fit)
        between = np.column_stack(
            [np.interp(stamps[left], stamps[used], fixes[used, i]) for i in (0, 1)]
        )
        row["interpolated"] = _away(between, fixes[left])
        carried = through_fixes(times, dead.poses, stamps[used], fixes[used], stamps[left])
        row["residuals"] = _away(carried, fixes[left])
        rows[gap] = row
    return {"fit": fit, "rows": rows}


def _fitted(data: dict, used: np.ndarray, fit) -> float:
    """The smoother's mean distance (m) to the fixes left out, the ``used`` fixes' settings
    those of ``fit`` (a ``FixFit``)."""
    stamps, fixes = data["fix_times"][used], data["fixes"][used]
    return _smoothed(
        data, ~used, fit.measurements(stamps, fixes), fit.settings(EstimatorSettings()),
        initial_pose=fit.start, initial_covariance=fit.start_covariance,
    )[0]  # fmt: skip


def _away(points: np.ndarray, fixes: np.ndarray) -> float:
    """The mean distance from ``points`` to ``fixes``, m."""
    return float(np.mean(np.hypot(*(points - fixes).T)))


def _smoothed(
    data: dict, left: np.ndarray, measurements: list, settings: EstimatorSettings, **start
) -> tuple[float, int]:
    """The smoother's mean distance (m) to the fixes ``left`` out, where it puts them (its
    position plus the offset), and how many fixes the gate refused."""
    stamps, times = data["fix_times"][left], data["times"]
    run = estimate_trajectory(
        HUSKY, times, data["increments"], gyro=data["gyro"], measurements=measurements,
        settings=settings, **start,
    )  # fmt: skip
    at = np.column_stack([np.interp(stamps, times, run.states[:, k]) for k in range(ekf.N)])
    placed = at[:, :2] + at[:, ekf.OFFSET : ekf.OFFSET + 2]
    return _away(placed, data["fixes"][left]), run.rejected


def distance_scale(data: dict, fit) -> dict:
    """The wheels' distance scale, the fit's and the filter's state's (started where the
    identification leaves it, the fit's standard error its prior), and the gyro-heading dead
    reckoning's ATE (m) with the wheels so scaled."""
    run = estimate_trajectory(
        HUSKY, data["times"], data["increments"], gyro=data["gyro"],
        measurements=fit.measurements(data["fix_times"], data["fixes"]),
        settings=fit.settings(
            EstimatorSettings(distance_scale=Prior(fit.distance_scale, fit.scale_error))
        ),
        initial_pose=fit.start, initial_covariance=fit.start_covariance,
    )  # fmt: skip
    state = float(run.states[-1, ekf.DISTANCE])
    sigma = math.sqrt(run.state_covariances[-1, ekf.DISTANCE, ekf.DISTANCE])

    def scaled_ate(scale: float) -> float:
        wheels = dd.DiffDrive(wheel_radius=HUSKY.wheel_radius * scale, track_width=0.555)
        gyro_run = estimate_trajectory(
            wheels, data["times"], data["increments"], gyro=data["gyro"],
            settings=EstimatorSettings("gyro"), initial_pose=data["start"], smooth=False,
        )  # fmt: skip
        return against_gps(data, gyro_run)

    return {
        "fit": (fit.fitted_scale, fit.scale_error, scaled_ate(fit.fitted_scale)),
        "state": (state, sigma, scaled_ate(state)),
        "nominal": scaled_ate(1.0),
    }


def consistency_against_gps(data: dict, figure: Path) -> dict:
    """How honest the gyro estimate's covariance is against the fixes, with no setting given
    (the gyro's identified, the library's default wheel noise): the estimate moved onto the
    fixes by the rigid motion that best fits them, its covariance turned with it and each
    fix's reported variance added (the reference's own noise, as ``noise.covariances`` adds
    it). ``figure``: the x and y errors with their 2-sigma bands."""
    from diffdrive.evaluation import consistency
    from diffdrive.plot import plot_error_bands

    estimate = estimate_trajectory(
        HUSKY, data["times"], data["increments"], gyro=data["gyro"],
        settings=EstimatorSettings("gyro"), initial_pose=data["start"], smooth=False,
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
    gaps = fix_gaps(data)
    print(f"GPS, identified from the receiver's {gaps['fit'].fixes} fixes:")
    for line in gaps["fit"].report:
        print(f"  {line}")
    print(
        "one fix used every g s, no setting given: mean distance (m) to the fixes left out, "
        "smoothed (the white noise taken) | interpolating the used fixes | dead reckoning plus "
        "their residuals | smoothed with the whole stream's settings"
    )
    for gap, row in gaps["rows"].items():
        print(
            f"  {gap:g} s ({row['used']} used, {row['refused']} refused): "
            f"{row['smoothed']:.3f} (white {row['white']:.3f} m) | {row['interpolated']:.3f} "
            f"({row['smoothed'] / row['interpolated']:.3f}x) | {row['residuals']:.3f} "
            f"({row['smoothed'] / row['residuals']:.3f}x) | {row['whole']:.3f}"
        )
    sweep = gaps["rows"][SWEPT]["sweep"]
    print(
        f"at {SWEPT:g} s, the smoother with the fixes' white noise taken as "
        + ", ".join(f"{white:g} m: {away:.3f}" for white, away in sweep.items())
    )
    scale = distance_scale(data, gaps["fit"])
    (fitted, error, fitted_ate), (state, sigma, state_ate) = scale["fit"], scale["state"]
    print(
        f"distance scale: fitted {fitted:.4f} +- {error:.4f} (gyro dead reckoning so scaled "
        f"{fitted_ate:.3f} m, unscaled {scale['nominal']:.3f} m); the filter's state, from "
        f"{gaps['fit'].distance_scale:.4f} +- {error:.4f}, ends at {state:.4f} +- {sigma:.4f} "
        f"({state_ate:.3f} m)"
    )

    honest = consistency_against_gps(data, args.figure)
    print(
        f"the gyro estimate's covariance against GPS (with each fix's reported variance): "
        f"ANEES {honest['anees']:.2f}, {honest['inside_95']:.0%} inside the 95 % ellipse, "
        f"{honest['inside_50']:.0%} inside the 50 % one; figure: {args.figure}"
    )


if __name__ == "__main__":
    main()
