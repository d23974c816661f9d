"""The OptiOdom recordings: a noise model identified on other experiments, and how honest the
covariance it predicts is on runs it never saw.

For each experiment of ``../shared/data/optiodom-diffdrive``: the geometry calibrated
(least squares) and the noise model identified (``diffdrive.calibration.noise.identify``) on
the other experiments of the same kind of path (and, in a second table, on all the other
experiments); then, on this experiment's runs, the odometry with the calibrated geometry,
the covariance the model predicts (``noise.covariances``) and its consistency against the
motion capture (``evaluation.consistency``): the share of poses inside the 95 % ellipse and
ANEES, pooled over the experiment's runs. A term the training runs cannot
identify is left out (and named); ``--seconds`` thins the runs to one pose every so often.

    python examples/noise_model.py [--data ../shared/data/optiodom-diffdrive]
        [--bags ../shared/data/ros-bags] [--figure FIGURE.png]

Then the model's best chance: calibrated and identified on all ten experiments and scored on
each (in-sample), and scored on 30 references it draws itself on each experiment's runs
(``noise.draw_reference``), which it passes if its terms can make errors like these.

Last, the TurtleBot3 bag against ``/odom`` (one run: what it can identify, in-sample), and
the figure: its errors against time with their 2-sigma bands.
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import numpy as np

from diffdrive.calibration import noise
from diffdrive.io.optiodom import optiodom_robot, read_optiodom_run

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "optiodom-diffdrive"


def load(folder: Path) -> dict[str, tuple[str, list]]:
    """Each experiment's kind of path and its runs, ``(increments, truth)``."""
    kinds: dict[str, str] = {}
    with (folder / "runs_index.csv").open() as index:
        for row in csv.DictReader(index):
            kinds[row["experiment"]] = row["path_type"]
    experiments = {}
    for experiment, kind in sorted(kinds.items()):
        paths = sorted((folder / kind / experiment).glob("*_run-*.csv"))
        runs = [(run.increments(), run.truth) for run in map(read_optiodom_run, paths)]
        experiments[experiment] = (kind, runs)
    return experiments


def held_out(experiments, same_kind: bool) -> dict[str, dict[str, object]]:
    """Each experiment scored by ``noise.cross_validate`` over its kind's experiments (or all
    of them)."""
    pools: dict[str, dict[str, list]] = {}
    for name, (kind, runs) in experiments.items():
        pools.setdefault(kind if same_kind else "all", {})[name] = runs
    scores = {}
    for groups in pools.values():
        scores.update(noise.cross_validate(optiodom_robot(), groups))
    table = {}
    for experiment, (kind, runs) in experiments.items():
        score = scores[experiment]
        model, found = score.model, score.consistency
        table[experiment] = {
            "kind": kind,
            "runs": len(runs),
            "inside_95": found.inside_95,
            "anees": found.anees,
            "k": model.k,
            "radius_sigma": model.radius_sigma,
            "track_sigma": model.track_sigma,
            "reference_sigma": model.reference_sigma,
            "left_out": ", ".join(score.left_out) or "-",
        }
    return table


def passes(found) -> bool:
    """The test of one experiment: 95 % coverage of 0.80 or more, and ANEES in [1/3, 3]."""
    return found.inside_95 >= 0.80 and 1 / 3 <= found.anees <= 3


def in_sample(experiments, draws: int = 30, seed: int = 0) -> dict[str, object]:
    """The geometry calibrated and the model identified on every run, then each experiment
    scored against its reference and against ``draws`` references the model itself draws on
    its runs (``noise.draw_reference``): the model's best chance, and what it would pass if
    the errors were its own."""
    from diffdrive.calibration import calibrate

    every = [run for _, runs in experiments.values() for run in runs]
    robot = calibrate(optiodom_robot(), every, "least_squares").robot.equivalent
    model, _ = noise.identify_what_it_can(robot, every)
    rng = np.random.default_rng(seed)
    real, own = {}, {}
    for name, (_, runs) in experiments.items():
        predicted = [noise.covariances(robot, i, truth[0], model) for i, truth in runs]
        real[name] = _score(predicted, [truth for _, truth in runs])
        drawn = [
            [noise.draw_reference(robot, i, truth[0], model, rng) for i, truth in runs]
            for _ in range(draws)
        ]
        own[name] = float(np.mean([passes(_score(predicted, refs)) for refs in drawn]))
    return {"model": model, "real": real, "own": own}


def _score(predicted: list, references: list):
    """The consistency of the predicted ``(poses, covariances)`` of runs, pooled, against
    their ``references`` (all poses but the starts)."""
    from diffdrive.evaluation import consistency

    return consistency(
        np.concatenate([poses[1:] for poses, _ in predicted]),
        np.concatenate([covariance[1:] for _, covariance in predicted]),
        np.concatenate([reference[1:] for reference in references]),
    )


def turtlebot3(bags: Path, figure: Path) -> str:
    """The TurtleBot3 bag against ``/odom``, one run: what can be identified on it, and the
    consistency of the covariance it then predicts on the same run; ``figure``: each error
    with its 2-sigma band."""
    import diffdrive as dd
    from diffdrive.evaluation import consistency, interpolate
    from diffdrive.io import ros
    from diffdrive.plot import plot_error_bands

    bag = bags / "turtlebot3_fuse.bag"
    run = ros.read_joint_states(bag, "wheel_left_joint", "wheel_right_joint")
    odom = ros.read_odometry(bag, "/odom")
    run = run.rows((run.times >= odom.times[0]) & (run.times <= odom.times[-1]))
    truth = interpolate(odom.times, odom.poses, run.times)
    robot = dd.DiffDrive(left_wheel_radius=0.03256, right_wheel_radius=0.03252, track_width=0.2955)
    increments = run.increments()
    model, left_out = noise.identify_what_it_can(robot, [(increments, truth)])
    poses, predicted = noise.covariances(robot, increments, truth[0], model)
    found = consistency(poses[1:], predicted[1:], truth[1:])
    figure.parent.mkdir(parents=True, exist_ok=True)
    title = "TurtleBot3 against /odom, the model identified on it"
    plot_error_bands(run.times[1:], poses[1:], predicted[1:], truth[1:], figure, title)
    return (
        f"TurtleBot3 against /odom: k {model.k:.2g} m, reference {model.reference_sigma:.2f} m "
        f"and {model.reference_heading_sigma:.2f} rad ({', '.join(left_out)} left out); "
        f"{found.inside_95:.0%} inside the 95 % ellipse, ANEES {found.anees:.1f}"
    )


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DATA)
    parser.add_argument("--bags", type=Path, default=DATA.parent / "ros-bags")
    parser.add_argument("--figure", type=Path, default=Path("out/figures/noise_turtlebot3.png"))
    args = parser.parse_args(argv)
    experiments = load(args.data)
    for same_kind in (True, False):
        table = held_out(experiments, same_kind)
        trained = "the other experiments of its kind" if same_kind else "all other experiments"
        print(f"\nidentified on {trained}:\n")
        print(
            "| experiment | kind | runs | inside 95 % | ANEES | k, m | radius sigma | track "
            "sigma | reference sigma, m | left out |"
        )
        print("|---|---|---|---|---|---|---|---|---|---|")
        for experiment, row in table.items():
            print(
                f"| {experiment} | {row['kind']} | {row['runs']} | {row['inside_95']:.2f} | "
                f"{row['anees']:.2f} | {row['k']:.2g} | {row['radius_sigma']:.4f} | "
                f"{row['track_sigma']:.4f} | {row['reference_sigma']:.4f} | {row['left_out']} |"
            )
        good = sum(r["inside_95"] >= 0.80 and 1 / 3 <= r["anees"] <= 3 for r in table.values())
        print(
            f"\n95 % coverage >= 0.80 and ANEES in [1/3, 3] ({trained}): {good} of "
            f"{len(table)} experiments"
        )
    found = in_sample(experiments)
    real, own = found["real"], found["own"]
    print("\nidentified on all ten (in-sample), and on references the model draws itself:\n")
    print("| experiment | inside 95 % | ANEES | passes | passes on its own draws |")
    print("|---|---|---|---|---|")
    for name, score in real.items():
        print(
            f"| {name} | {score.inside_95:.2f} | {score.anees:.2f} | "
            f"{'yes' if passes(score) else 'no'} | {own[name]:.0%} |"
        )
    print(
        f"\nin-sample: {sum(map(passes, real.values()))} of {len(real)} experiments pass; on "
        f"the model's own draws {np.mean(list(own.values())):.0%} of experiments do"
    )
    print()
    print(turtlebot3(args.bags, args.figure))
    print(f"figure: {args.figure}")


if __name__ == "__main__":
    main()
