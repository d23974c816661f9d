"""Calibrate the OptiOdom robot on its own runs, next to the paper's methods, and draw it.

For every experiment in ../shared/data/optiodom-diffdrive, the largest position error over its
runs (m), with rk2 odometry from each run's first ground-truth pose:

- nominal: the robot's nominal geometry (L 0.2 m, D 0.084 m);
- the authors' figures, from their spreadsheet: UMBmark and Jung & Chung (square runs),
  Ivanjko et al. (Ivanjko runs), OptiOdom (all);
- ours with the paper's protocol (calibrate on an experiment's runs, evaluate on the same
  runs): robust least squares, and minimax (the largest position error itself);
- ours with a stricter protocol the paper does not use: calibrate on the runs of the other
  nine experiments only, evaluate on this one, which the calibration never saw.

Then a second table, scored on runs the calibration never saw: each experiment's runs left out
one at a time, each scored by the calibration on the others (``cross_validate``), for least
squares and minimax, each alone and with the extra parameters ``axle_offset`` and
``heading_offset``, and for the per-step fit ``increments``, a step and 20 steps at a time.
A fold whose remaining runs cannot identify the parameters is refused ("refused"), never
scored with a guessed robot.

Prints both Markdown tables and draws one run: ground truth, nominal and calibrated odometry.

    pip install -e '.[examples]'
    python examples/optiodom_calibration.py [--data ../shared/data/optiodom-diffdrive]
        [--output out/figures/optiodom_calibration.png]
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import numpy as np

from diffdrive.calibration import Increments, LeastSquares, calibrate
from diffdrive.calibration.cross_validation import cross_validate
from diffdrive.evaluation import run_errors, worst
from diffdrive.io.optiodom import optiodom_robot, read_optiodom_run
from diffdrive.simulation import dead_reckon

ROOT = Path(__file__).resolve().parents[1]
AUTHORS = {
    "UMBmark": "UMBmark",
    "Jung & Chung": "Jung & Chung",
    "Ivanjko": "Ivanjko et al.",
    "OptiOdom": "OptiOdom",
}
DRAWN = "circular/231220200141"


def load(folder: Path) -> tuple[dict[str, list], dict[str, dict[str, float]]]:
    """The runs of each experiment present, and the authors' calibrated max position errors."""
    authors: dict[str, dict[str, float]] = {}
    with (folder / "reference_results_from_authors.csv").open() as table:
        for row in csv.DictReader(table):
            if row["note"] or not (folder / row["experiment"]).is_dir():
                continue
            name = next(label for key, label in AUTHORS.items() if row["method"].startswith(key))
            authors.setdefault(row["experiment"], {})[name] = float(row["calib_max_pos_err_m"])
    experiments = {}
    for experiment in authors:
        paths = sorted((folder / experiment).glob("*_run-*.csv"))
        experiments[experiment] = [
            (run.increments(), run.truth) for run in map(read_optiodom_run, paths)
        ]
    return experiments, authors


def largest_error(robot, runs) -> float:
    return worst([run_errors(dead_reckon(robot, i, t[0], "rk2"), t) for i, t in runs]).max_position


def results(experiments: dict[str, list]) -> dict[str, dict[str, float]]:
    """Our figures for each experiment, under both protocols."""
    nominal = optiodom_robot()
    table = {}
    for experiment, runs in experiments.items():
        others = [run for name, rs in experiments.items() if name != experiment for run in rs]
        row = {"nominal": largest_error(nominal, runs)}
        for method in ("least_squares", "minimax"):
            row[method] = largest_error(
                calibrate(nominal, runs, method, integration="rk2").robot, runs
            )
            unseen = calibrate(nominal, others, method, integration="rk2").robot
            row[f"{method}, unseen"] = largest_error(unseen, runs)
        table[experiment] = row
    return table


OFFSETS = LeastSquares(extra=("axle_offset", "heading_offset"))
HELD_OUT = {  # column: (method, its options)
    "least_squares": ("least_squares", None),
    "with offsets": ("least_squares", OFFSETS),
    "minimax": ("minimax", None),
    "minimax with offsets": ("minimax", OFFSETS),
    "increments": ("increments", None),
    "increments, window 20": ("increments", Increments(window=20)),
}


def held_out(experiments: dict[str, list]) -> dict[str, dict[str, object]]:
    """Per experiment of 2 runs or more: its run count, and the in-sample and
    leave-one-run-out worst-run max position errors (m) of each column, or "refused"."""
    table = {}
    for experiment, runs in experiments.items():
        if len(runs) < 2:
            continue
        row: dict[str, object] = {"runs": len(runs)}
        for column, (method, options) in HELD_OUT.items():
            cv = cross_validate(optiodom_robot(), runs, method, "loo", options, integration="rk2")
            row[f"{column}, in-sample"] = cv.in_sample.max_position
            row[f"{column}, held out"] = (
                "refused" if cv.held_out is None or cv.refused else cv.held_out.max_position
            )
        table[experiment] = row
    return table


def held_out_markdown(rows: dict[str, dict[str, object]], authors) -> str:
    """The held-out table, mm; the authors' in-sample OptiOdom figure first."""
    columns = [c for c in rows[next(iter(rows))] if c != "runs"]
    lines = [
        "| experiment | runs | OptiOdom (theirs, in-sample) | " + " | ".join(columns) + " |",
        "|---" * (len(columns) + 3) + "|",
    ]
    for experiment, row in rows.items():
        cells = [f"{1000 * authors[experiment]['OptiOdom']:.1f}"]
        cells += [row[c] if isinstance(row[c], str) else f"{1000 * row[c]:.1f}" for c in columns]
        lines.append(f"| {experiment} | {row['runs']} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def markdown(ours: dict[str, dict[str, float]], authors: dict[str, dict[str, float]]) -> str:
    columns = [
        "nominal",
        *AUTHORS.values(),
        "least_squares",
        "minimax",
        "least_squares, unseen",
        "minimax, unseen",
    ]
    lines = [
        "| experiment | " + " | ".join(columns) + " |",
        "|---" * (len(columns) + 1) + "|",
    ]
    sums = {column: [] for column in columns}
    for experiment, row in ours.items():
        values = {**row, **authors[experiment]}
        cells = []
        for column in columns:
            value = values.get(column)
            cells.append("" if value is None else f"{1000 * value:.1f}")
            if value is not None:
                sums[column].append(value)
        lines.append(f"| {experiment} | " + " | ".join(cells) + " |")
    means = [f"{1000 * np.mean(sums[c]):.1f}" if len(sums[c]) == len(ours) else "" for c in columns]
    lines.append("| mean of all 10 | " + " | ".join(means) + " |")
    return "\n".join(lines)


def draw(runs: list, output: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    nominal = optiodom_robot()
    calibrated = calibrate(nominal, runs, "minimax", integration="rk2").robot
    increments, truth = runs[0]
    figure, ax = plt.subplots(figsize=(7, 6), layout="constrained")
    ax.plot(truth[:, 0], truth[:, 1], color="0.5", linewidth=3, label="ground truth (OptiTrack)")
    for robot, label in [(nominal, "nominal odometry"), (calibrated, "calibrated (minimax)")]:
        poses = dead_reckon(robot, increments, truth[0], "rk2")
        error = run_errors(poses, truth).max_position
        ax.plot(poses[:, 0], poses[:, 1], label=f"{label}: max error {1000 * error:.0f} mm")
    ax.plot(*truth[0, :2], "k^", label="start")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set(xlabel="x, m", ylabel="y, m", title=f"OptiOdom {DRAWN}, run 01")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best")
    figure.savefig(output, dpi=100)
    plt.close(figure)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--data", type=Path, default=ROOT.parent / "shared" / "data" / "optiodom-diffdrive"
    )
    parser.add_argument("--output", type=Path, default=Path("out/figures/optiodom_calibration.png"))
    args = parser.parse_args(argv)
    if not args.data.is_dir():
        raise SystemExit(f"the OptiOdom data is expected in {args.data}")
    experiments, authors = load(args.data)
    print("largest position error over each experiment's runs, mm\n")
    print(markdown(results(experiments), authors))
    print("\nthe same, on runs held out one at a time (leave one run out), mm\n")
    print(held_out_markdown(held_out(experiments), authors))
    args.output.parent.mkdir(parents=True, exist_ok=True)
    draw(experiments[DRAWN], args.output)
    print(f"\nfigure: {args.output}")


if __name__ == "__main__":
    main()
