"""OptiOdom's motion capture as a stand-in camera: calibration from driving, checked against
the full motion-capture calibration of the same runs.

For each experiment of ``../shared/data/optiodom-diffdrive`` the motion capture is thinned
to 2 Hz, given 1 cm and 0.5 degree of noise (seeded) and stamped 50 ms late: a camera.
``calibrate_to_reference`` calibrates the wheels, the camera's mount and its clock on the
experiment's runs together, every noise figure identified from the log (started at twice the
camera's and the library's wheel default). Against the least-squares calibration on the full
motion capture (``calibrate(..., "least_squares")``) it prints, per experiment:

- ``z``: the stand-in's left radius, right radius and track less the least-squares', in the
  stand-in's standard errors (target: within 2);
- the camera's noise and the wheels' k as identified;
- held out: each run left out in turn, both calibrations made on the others, the run's final
  position error dead-reckoned with each (target: the stand-in's within 10 % of the
  least-squares', pooled over every fold);
- the bound: the same held-out error for geometries drawn about the least-squares fold's from
  the stand-in's covariance, the precision its readings allow (the Cramer-Rao bound of that
  drive, as the fit is efficient): what any calibration from this camera would have.

    python examples/standin_camera.py [--data ../shared/data/optiodom-diffdrive] [--only EXP]
"""

from __future__ import annotations

import argparse
import csv
import math
from pathlib import Path

import numpy as np

from diffdrive.calibration import (
    CalibrationError,
    ReferenceSettings,
    calibrate,
    calibrate_to_reference,
)
from diffdrive.evaluation import run_errors
from diffdrive.io.optiodom import optiodom_robot, read_optiodom_run
from diffdrive.simulation import dead_reckon

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "optiodom-diffdrive"
CAMERA = (0.01, 0.01, math.radians(0.5))  # m, m, rad
PERIOD = 10  # motion-capture rows per camera reading: 20 Hz to 2 Hz
DELAY = 0.05  # s the camera's stamps run late
DRAWS = 200  # geometries drawn for the bound
GEOMETRY = ("left_radius", "right_radius", "track")


def experiments(data: Path) -> dict[str, list]:
    """Each experiment's runs, by its name, in the index's order of kinds."""
    with (data / "runs_index.csv").open() as index:
        kinds = {row["experiment"]: row["path_type"] for row in csv.DictReader(index)}
    return {
        name: [read_optiodom_run(path) for path in sorted((data / kind / name).glob("*_run-*.csv"))]
        for name, kind in sorted(kinds.items())
    }


def camera(run, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """The stand-in camera's stamps (s, late by ``DELAY``) and noisy poses ``(K, 3)``."""
    rows = np.arange(0, len(run.times), PERIOD)
    noise = np.array(CAMERA) * rng.standard_normal((len(rows), 3))
    return run.times[rows] + DELAY, run.truth[rows] + noise


def standin(runs: list, rng: np.random.Generator):
    """The calibration against the stand-in camera, its noise identified from the log."""
    seen = [camera(run, rng) for run in runs]
    return calibrate_to_reference(
        optiodom_robot(),
        [run.times for run in runs],
        [run.increments() for run in runs],
        [stamps for stamps, _ in seen],
        [poses for _, poses in seen],
        sigma=tuple(2 * np.array(CAMERA)),
        settings=ReferenceSettings(identify_noise=True),
    )


def least_squares(runs: list):
    """The full motion-capture least-squares calibration of ``runs``' geometry."""
    return calibrate(optiodom_robot(), [(run.increments(), run.truth) for run in runs])


def final_error(robot, run) -> float:
    """The run's final position error (m), dead-reckoned with ``robot`` from its start."""
    return run_errors(dead_reckon(robot, run.increments(), run.truth[0]), run.truth).final_position


def geometry(robot) -> np.ndarray:
    return np.array([robot.left_wheel_radius, robot.right_wheel_radius, robot.track_width])


def bound(found, reference, run, rng: np.random.Generator) -> float:
    """The mean held-out final error of geometries drawn about ``reference``'s with
    ``found``'s covariance of the radii and track."""
    index = [found.estimated.index(name) for name in GEOMETRY]
    spread = found.covariance[np.ix_(index, index)]
    draws = rng.multivariate_normal(geometry(reference.robot), spread, size=DRAWS)
    robot = reference.robot
    return float(np.mean([final_error(robot.with_geometry(*draw), run) for draw in draws]))


def held_out(runs: list, rng: np.random.Generator) -> list[tuple[float, float, float]]:
    """Each run left out in turn: its final error with the stand-in's calibration, the
    least-squares' and the bound's, from the other runs; folds the least squares refuses
    (the others turn one way only, say) are skipped."""
    folds = []
    for k, run in enumerate(runs):
        others = runs[:k] + runs[k + 1 :]
        try:
            reference = least_squares(others)
        except CalibrationError:
            continue
        found = standin(others, rng)
        errors = (final_error(found.robot, run), final_error(reference.robot, run))
        folds.append((*errors, bound(found, reference, run, rng)))
    return folds


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DATA)
    parser.add_argument("--only", nargs="+", metavar="EXPERIMENT", help="these experiments alone")
    args = parser.parse_args(argv)
    found_z, folds = [], []
    for name, runs in experiments(args.data).items():
        if args.only and name not in args.only:
            continue
        rng = np.random.default_rng(int(name) % 2**32)
        try:
            found = standin(runs, rng)
            reference = least_squares(runs)
        except (ValueError, CalibrationError) as refused:
            print(f"{name}: {len(runs)} runs, refused: {refused}")
            continue
        errors = found.standard_errors()
        spread = np.array([errors[name] for name in GEOMETRY])
        z = (found.values[:3] - geometry(reference.robot)) / spread
        found_z.append(z)
        assert found.noise is not None
        noise = found.noise.values
        line = (
            f"{name}: {len(runs)} runs, z {' '.join(f'{v:+.2f}' for v in z)}, camera "
            f"{1e3 * noise['reference']:.1f} mm {math.degrees(noise['reference_heading']):.2f} "
            f"deg, k {noise['wheels']:.2g} m, delay {1e3 * found.value('offset'):.0f} +- "
            f"{1e3 * errors['offset']:.0f} ms"
        )
        if len(runs) > 1:
            these = held_out(runs, rng)
            folds += these
            if these:
                mean = np.mean(these, axis=0) * 1e3
                line += f"; held out {len(these)}: {mean[0]:.1f} vs {mean[1]:.1f} mm"
                line += f", bound {mean[2]:.1f}"
        print(line, flush=True)
    largest = float(np.max(np.abs(found_z))) if found_z else math.nan
    pooled = np.mean(folds, axis=0) if folds else np.full(3, math.nan)
    ratio, expected = pooled[0] / pooled[1], pooled[2] / pooled[1]
    print(
        f"largest |z| {largest:.2f} over {len(found_z)} experiments (target 2); held out over "
        f"{len(folds)} folds: the stand-in's mean final error {1e3 * pooled[0]:.1f} mm against "
        f"the least squares' {1e3 * pooled[1]:.1f} mm, {ratio:.2f} times (target 1.10); the "
        f"bound {1e3 * pooled[2]:.1f} mm, {expected:.2f} times"
    )
    return {"z": largest, "ratio": ratio, "bound": expected, "folds": len(folds)}


if __name__ == "__main__":
    main()
