"""The OptiOdom recordings: a noise model identified on other experiments (or other
sessions), and how honest the covariance it predicts is on runs it never saw.

For each experiment of ``../shared/data/optiodom-diffdrive``: the geometry calibrated (least
squares) on the other nine experiments pooled and the noise model identified on them
(``diffdrive.calibration.noise.cross_validate_noise``): each wheel's random walk, and the geometry
as a random constant per experiment with its full 3x3 covariance, the motion capture held
at its stated accuracy (``noise.MOTION_CAPTURE``) rather than fitted. Then, on this
experiment's runs, the odometry with the calibrated geometry, the covariance the model
predicts (``noise.covariances``) and its consistency against the motion capture
(``evaluation.consistency``): the share of poses inside the 95 % ellipse and ANEES, pooled
over the experiment's runs. An experiment passes when the model is not overconfident on it:
coverage 0.80 or more with ANEES 3 or less. Pooled over every held-out pose, the share
inside and ANEES say whether the model is right on average; and each held-out model is
scored the same way on 30 references it draws itself on the experiment's runs
(``noise.draw_reference``, one geometry a draw), which it should pass if its terms can make
errors like these. Then the same held out by session (``io.optiodom_sessions``: every
experiment of the held-out one's sitting left out of the training).

    python examples/noise_model.py [--data ../shared/data/optiodom-diffdrive]
        [--bags ../shared/data/ros-bags] [--figure FIGURE.png]

Last, the TurtleBot3 bag against ``/odom`` (one run: what it can identify, in-sample), and
the figure: its errors against time with their 2-sigma bands.
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import numpy as np

from diffdrive.calibration import noise
from diffdrive.io.optiodom import optiodom_robot, optiodom_sessions, read_optiodom_run

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "optiodom-diffdrive"
STATED = {
    "reference_sigma": noise.MOTION_CAPTURE[0],
    "reference_heading_sigma": noise.MOTION_CAPTURE[1],
}
DRAWS = 30


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


def passes(found) -> bool:
    """Not overconfident on one experiment: 95 % coverage of 0.80 or more, ANEES 3 or less."""
    return found.inside_95 >= 0.80 and found.anees <= 3


def held_out(experiments, by_session: bool, draws: int = DRAWS, seed: int = 0) -> dict:
    """Each experiment scored by ``noise.cross_validate_noise`` over all the others (or all the
    other sessions'), and the share of ``draws`` references its model draws itself that it
    passes."""
    groups = {name: runs for name, (_, runs) in experiments.items()}
    sessions = optiodom_sessions(groups) if by_session else None
    scores = noise.cross_validate_noise(optiodom_robot(), groups, sessions=sessions, fixed=STATED)
    rng = np.random.default_rng(seed)
    table = {}
    for experiment, (kind, runs) in experiments.items():
        held = scores[experiment]
        table[experiment] = {
            "kind": kind,
            "runs": len(runs),
            "session": (sessions or optiodom_sessions(groups))[experiment],
            "held": held,
            "own": _own_draws(held, runs, draws, rng),
        }
    return table


def _own_draws(held, runs, draws, rng) -> float:
    """The share of ``draws`` references, each one draw of the geometry for all ``runs``, on
    which the held-out model passes."""
    predicted = [noise.covariances(held.robot, i, truth[0], held.model) for i, truth in runs]
    passed = 0
    for _ in range(draws):
        geometry = held.model.draw_geometry(rng)
        references = [
            noise.draw_reference(held.robot, i, t[0], held.model, rng, geometry=geometry)
            for i, t in runs
        ]
        passed += passes(_score(predicted, references))
    return passed / draws


def pooled(table) -> tuple[float, float, int]:
    """The share inside the 95 % ellipse and ANEES over every held-out pose, and their
    count."""
    from scipy.stats import chi2

    nees = np.concatenate([row["held"].consistency.nees for row in table.values()])
    nees = nees[np.isfinite(nees)]
    return float(np.mean(nees <= chi2.ppf(0.95, 3))), float(nees.mean() / 3), len(nees)


def _score(predicted: list, references: list):
    """The consistency of the predicted ``(poses, covariances)`` of runs, pooled, against
    their ``references`` (all poses but the starts)."""
    from diffdrive.evaluation import consistency

    return consistency(
        np.concatenate([poses[1:] for poses, _ in predicted]),
        np.concatenate([covariance[1:] for _, covariance in predicted]),
        np.concatenate([reference[1:] for reference in references]),
    )


def report(table, by_session: bool) -> None:
    """The table of one way of holding out, and its counts."""
    trained = "the other sessions" if by_session else "the nine other experiments"
    print(f"\nheld out, trained on {trained}:\n")
    print(
        "| experiment | kind | session | runs | inside 95 % | ANEES | passes | k left, right (m) "
        "| radius, track sigma | radii's correlation | passes on its own draws |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for experiment, row in table.items():
        found, model = row["held"].consistency, row["held"].model
        print(
            f"| {experiment} | {row['kind']} | {row['session']} | {row['runs']} | "
            f"{found.inside_95:.2f} | {found.anees:.2f} | {'yes' if passes(found) else 'no'} | "
            f"{model.k_left:.2g}, {model.k_right:.2g} | {model.radius_sigma:.4f}, "
            f"{model.track_sigma:.4f} | {model.correlation[0, 1]:.2f} | {row['own']:.0%} |"
        )
    good = sum(passes(row["held"].consistency) for row in table.values())
    inside, anees, poses = pooled(table)
    own = np.mean([row["own"] for row in table.values()])
    way = "by session" if by_session else "by experiment"
    print(f"\n{way}: coverage >= 0.80 with ANEES <= 3 on {good} of {len(table)} experiments")
    print(
        f"{way}, pooled over {poses} poses: {inside:.1%} inside the 95 % ellipse, ANEES {anees:.2f}"
    )
    print(f"{way}, on references the models draw themselves: {own:.0%} pass")


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
        f"TurtleBot3 against /odom: k {model.k_left:.2g} m left, {model.k_right:.2g} m right, "
        f"reference {model.reference_sigma:.2f} m "
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
    for by_session in (False, True):
        report(held_out(experiments, by_session), by_session)
    print()
    print(turtlebot3(args.bags, args.figure))
    print(f"figure: {args.figure}")


if __name__ == "__main__":
    main()
