"""Real data: dead reckoning on the OptiOdom runs reproduces the authors' figures."""

import csv
import math
import re

import numpy as np
import pytest

import diffdrive as dd
from data import DATA, data_folder, rows_or_missing
from diffdrive.io.optiodom import OPTIODOM_TICKS_PER_REVOLUTION, optiodom_robot, read_optiodom_run

FOLDER = DATA / "optiodom-diffdrive"
# The runs the authors call outliers, for the rows "(without worse runs)" that leave them out.
OUTLIERS = {"square/231220200029": 2, "free/030120210006": 3}


def reference_rows():
    def rows():
        with (FOLDER / "reference_results_from_authors.csv").open() as table:
            found = [row for row in csv.DictReader(table) if (FOLDER / row["experiment"]).is_dir()]
        assert len(found) >= 10, "the reference table lists fewer experiments than are present"
        return found

    return rows_or_missing("optiodom-diffdrive", rows)


def run_errors(run, robot):
    """Max and final position error (m) and heading error (deg) of rk2 dead reckoning."""
    odometry = dd.Odometry(robot, "rk2", dd.Pose(*run.truth[0]), OPTIODOM_TICKS_PER_REVOLUTION)
    poses = []
    for (left, right), t in zip(run.wheels.tolist(), run.times.tolist(), strict=True):
        odometry.update_ticks(left, right, t)
        poses.append(odometry.pose.to_array())
    error = np.array(poses) - run.truth
    position = np.hypot(error[:, 0], error[:, 1])
    heading = np.degrees(np.abs(error[:, 2]))
    return np.array([position.max(), heading.max(), position[-1], heading[-1]])


@pytest.mark.parametrize("row", reference_rows(), ids=lambda r: f"{r['experiment']}{r['note']}")
def test_dead_reckoning_reproduces_the_authors_initial_errors(row):
    data_folder("optiodom-diffdrive")
    robot = optiodom_robot(
        float(row["init_L_m"] or 0.2),
        float(row["init_Dr_m"] or 0.084),
        float(row["init_Dl_m"] or 0.084),
    )
    runs = sorted((FOLDER / row["experiment"]).glob("*_run-*.csv"))
    if "without worse runs" in row["note"]:
        outlier = re.search(r"runs: (\d+)", row["note"])
        number = int(outlier.group(1)) if outlier else OUTLIERS[row["experiment"]]
        runs = [run for run in runs if not run.stem.endswith(f"run-{number:02d}")]
    worst = np.max([run_errors(read_optiodom_run(run), robot) for run in runs], axis=0)
    expected = [
        float(row[f"init_{name}"])
        for name in (
            "max_pos_err_m",
            "max_heading_err_deg",
            "max_final_pos_err_m",
            "max_final_heading_err_deg",
        )
    ]
    # The spreadsheet keeps 6 significant digits: 1e-5 m and 1e-3 degrees cover its rounding.
    np.testing.assert_allclose(worst[[0, 2]], [expected[0], expected[2]], rtol=0, atol=1e-5)
    np.testing.assert_allclose(worst[[1, 3]], [expected[1], expected[3]], rtol=0, atol=1e-3)
    assert math.isfinite(worst.sum())
