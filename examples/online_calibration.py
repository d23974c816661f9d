"""Calibration while the robot drives: the OnlineCalibrator's estimates settling on OptiOdom runs.

Each experiment's runs (../shared/data/optiodom-diffdrive) are streamed one 50 ms cycle at a
time: the wheel increments, and the motion-capture relative pose over the cycle; the
calibrator makes one measurement of every 20 cycles (its default window). Printed for each
experiment: the final estimates of the wheel radii and the track width, and their differences
from the batch answers on the same runs: the same linear model all at once
(``batch_solution``), the per-step fit (``calibrate(..., "increments")``) and whole-path least
squares. Then the same with a window of one cycle. The figure draws the estimates settling on
the first circular experiment (one run each way), against the batch answers.

    pip install -e '.[examples]'
    python examples/online_calibration.py [--data ../shared/data/optiodom-diffdrive]
        [--output out/figures/online_calibration.png]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from diffdrive import batch
from diffdrive.calibration import calibrate
from diffdrive.calibration.online import OnlineCalibrator
from diffdrive.io.optiodom import optiodom_robot, read_optiodom_run

ROOT = Path(__file__).resolve().parents[1]
EXPERIMENTS = ("circular/231220200141", "circular/250620202345", "free/030120210006")
NAMES = ("left wheel radius, mm", "right wheel radius, mm", "track width, mm")


def read_runs(folder: Path) -> list[tuple[np.ndarray, np.ndarray]]:
    """``(wheel-angle increments, ground-truth poses)`` of each run of an experiment."""
    paths = sorted(folder.glob("*_run-*.csv"))
    return [(run.increments(), run.truth) for run in map(read_optiodom_run, paths)]


def stream(runs: list, window: int = 20) -> tuple[OnlineCalibrator, np.ndarray]:
    """Every cycle of every run through one calibrator; its estimates after each cycle."""
    online = OnlineCalibrator(optiodom_robot(), window=window)
    history = []
    for increments, truth in runs:
        relative = batch.relative_to(truth[1:], truth[:-1])
        for k in range(len(increments)):
            online.update(*increments[k], relative[k])
            history.append(online.parameters)
    return online, np.array(history)


def batch_answers(runs: list, online: OnlineCalibrator) -> dict[str, np.ndarray]:
    # Streamed one after another, a window may span the end of one run and the start of the
    # next: their relative poses compose all the same, and the batch answer windows alike.
    increments = np.concatenate([i for i, _ in runs])
    relative = np.concatenate([batch.relative_to(t[1:], t[:-1]) for _, t in runs])
    found = {"same model, all at once": online.batch_solution(increments, relative)}
    for label, method in (
        ("per-step fit", "increments"),
        ("whole-path least squares", "least_squares"),
    ):
        robot = calibrate(optiodom_robot(), runs, method, integration="rk2").robot
        found[label] = np.array(
            [robot.left_wheel_radius, robot.right_wheel_radius, robot.track_width]
        )
    return found


def draw(history: np.ndarray, answers: dict[str, np.ndarray], title: str, output: Path) -> None:
    from matplotlib.figure import Figure

    figure = Figure(figsize=(12, 4), layout="constrained")
    figure.suptitle(title)
    for k, ax in enumerate(figure.subplots(1, 3)):
        ax.plot(1000 * history[:, k], color="tab:blue", label="online")
        for (label, values), style in zip(answers.items(), ("--", ":", "-."), strict=True):
            ax.axhline(1000 * values[k], linestyle=style, color="0.3", label=label)
        ax.set(xlabel="cycles (50 ms)", title=NAMES[k])
        ax.grid(True, alpha=0.3)
    ax.legend(loc="best")
    figure.savefig(output, dpi=100)


def report(name: str, runs: list, window: int) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Stream one experiment and print the estimates against the batch answers."""
    online, history = stream(runs, window)
    answers = batch_answers(runs, online)
    final = online.parameters
    print(
        f"{name}, window {window}: {len(history)} cycles, {online.accepted} measurements, "
        f"{online.rejected} gated out; radii {1000 * final[0]:.3f}, {1000 * final[1]:.3f} mm, "
        f"track {1000 * final[2]:.2f} mm"
    )
    for label, values in answers.items():
        difference = 100 * (final / values - 1)
        print(f"  against {label}: " + ", ".join(f"{d:+.2f} %" for d in difference))
    return history, answers


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--data", type=Path, default=ROOT.parent / "shared" / "data" / "optiodom-diffdrive"
    )
    parser.add_argument("--output", type=Path, default=Path("out/figures/online_calibration.png"))
    args = parser.parse_args(argv)
    drawn = None
    for window in (20, 1):
        for name in EXPERIMENTS:
            shown = report(name, read_runs(args.data / name), window)
            drawn = drawn or (name, *shown)
    args.output.parent.mkdir(parents=True, exist_ok=True)
    name, history, answers = drawn
    draw(history, answers, f"{name}: one run each way, 20 cycles a measurement", args.output)
    print(f"figure: {args.output}")


if __name__ == "__main__":
    main()
