"""``diffdrive evaluate``: a trajectory against ground truth."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

from diffdrive.cli.options import (
    TRAJECTORY_FILES,
    Command,
    Parents,
    add_datum_option,
    refuse_truth_topic_alone,
    refuse_unused,
)
from diffdrive.demo import (
    example_log,
    example_robot,
)
from diffdrive.evaluation import (
    RPE_PAIRS,
    alignment,
    associate,
    ate,
    consistency,
    interpolate,
    interpolate_covariances,
    path_errors,
    rpe,
    run_errors,
)
from diffdrive.io import TableError, read_trajectory
from diffdrive.io.trajectories import read_covariances
from diffdrive.simulation import dead_reckon


def _check_options(args: argparse.Namespace) -> None:
    """The pairing and window options, refused by their own names before any file is read."""
    refuse_truth_topic_alone(args)
    refuse_unused({"--align": args.align and not args.consistency}, "used only with --consistency")
    for option, value, allowed, rule in (
        ("--t-max-diff", args.t_max_diff, args.t_max_diff >= 0, "finite and >= 0"),
        ("--t-offset", args.t_offset, True, "finite"),
        ("--rpe", args.rpe, args.rpe > 0, "finite and > 0"),
    ):
        if not (math.isfinite(value) and allowed):
            raise ValueError(f"{option} must be {rule}, got {value}")


def run_evaluate(args: argparse.Namespace) -> int:
    _check_options(args)
    covariances = None
    if args.plan is not None:
        metrics = plan_metrics(args)
    elif args.input is None:
        log, robot = example_log(), example_robot()
        times, truth = log.times, log.truth
        if args.consistency:
            raise TableError(
                "--consistency needs an estimate that carries a covariance (diffdrive odometry "
                "--covariance writes one) and its --truth; the built-in example has none"
            )
        estimate = dead_reckon(robot, log.increments(), truth[0], "exact")
    else:
        if args.truth is None:
            raise TableError("evaluate needs --truth with a ground-truth trajectory or bag")
        _stage(args.input, "reading the trajectory")
        times, estimate = read_trajectory(args.input, args.time_unit, args.topic, args.datum)
        if args.consistency:
            covariances = read_covariances(args.input, len(times), args.time_unit, args.topic)
        _stage(args.truth, "reading the truth")
        truth_times, truth = read_trajectory(
            args.truth, args.time_unit, args.truth_topic, args.datum
        )
        _stage(args.input, f"pairing and measuring {len(times)} poses")
        for path, poses in ((args.input, estimate), (args.truth, truth)):
            if poses.ndim != 2:
                raise TableError(f"{path}: evaluate takes one robot; the file has {len(poses)}")
        if args.datum is not None and not any(np.isnan(p[:, 2]).all() for p in (estimate, truth)):
            raise TableError(
                f"--datum places GPS fixes: neither {args.input} nor {args.truth} is a "
                "NavSatFix topic"
            )
        _check_clocks(args, times, truth_times)
        times, estimate, truth, covariances = _paired(
            args, times, estimate, truth_times, truth, covariances
        )
    if args.plan is None:
        metrics = evaluation_metrics(args, times, estimate, truth)
    if covariances is not None:
        found = consistency(estimate, covariances, truth, aligned=args.align)
        if args.align:
            _warn_of_one_frame(estimate, covariances, truth, found)
        else:
            _warn_of_other_frames(estimate, covariances, truth, found)
        metrics.update(
            consistency_poses=found.used,
            consistency_dof=found.dof,
            anees=found.anees,
            inside_50_percent=found.inside_50,
            inside_95_percent=found.inside_95,
        )
    if args.json:
        print(json.dumps(metrics))
    else:
        for key, value in metrics.items():
            shown = (
                "n/a"
                if value is None
                else (f"{value:.6f}" if isinstance(value, float) else str(value))
            )
            print(f"{key:34} {shown:>12}")
    return 0


def _check_clocks(args, times: np.ndarray, truth_times: np.ndarray) -> None:
    """Refuse two inputs whose time spans (the trajectory's after --t-offset) are one span
    moved by more than a period (the larger median step of the two): two clocks, such as a
    bag's stamps and the trajectory they were made from, whose poses would be paired with
    those of other times. Spans that differ otherwise (a truth that starts earlier and ends
    later) are said in a warning."""
    shifted = times + args.t_offset
    period = max(float(np.median(np.diff(times))), float(np.median(np.diff(truth_times))))
    starts, ends = shifted[0] - truth_times[0], shifted[-1] - truth_times[-1]
    if max(abs(starts), abs(ends)) <= period:
        return
    spans = (
        f"{args.input} spans {shifted[0]:g} to {shifted[-1]:g} s (after --t-offset) and "
        f"{args.truth} {truth_times[0]:g} to {truth_times[-1]:g} s: they start {starts:+g} s and "
        f"end {ends:+g} s apart"
    )
    if abs(starts - ends) <= period:
        raise TableError(
            f"{spans}, the same span moved by more than a period ({period:g} s): two clocks, "
            f"whose poses would be paired with others of other times. Give --t-offset "
            f"{args.t_offset - starts:g} if the moves are the same, or compare on one clock "
            "(a synth run's table and bag share theirs; its bag holds the truth on "
            "/ground_truth)"
        )
    print(
        f"evaluate: warning: {spans}, more than a period ({period:g} s): only the poses "
        "within both spans are paired",
        file=sys.stderr,
    )


def _warn_of_other_frames(estimate, covariances, truth, found) -> None:
    """Say when the covariance fits the errors far better once the estimate is moved onto the
    truth by a rigid motion: the two are most likely in frames of their own (odometry's
    against GPS's east-north), and the raw errors measure that offset. Judged on the median
    NEES: the mean is the first poses', whose covariance is all but zero."""
    moved = consistency(estimate, covariances, truth, aligned=True)
    before, after = np.nanmedian(found.nees), np.nanmedian(moved.nees)
    if not before > 10.0 * after:
        return
    positions = np.column_stack([truth[:, :2], np.zeros(len(truth))])  # GPS: no heading
    motion = alignment(estimate, positions)
    print(
        f"evaluate: warning: the median NEES {before:.4g} falls to {after:.4g} once the "
        f"trajectory is moved onto the truth by a rigid motion (turned "
        f"{math.degrees(motion[2]):.1f} deg, shifted {math.hypot(*motion[:2]):.3g} m): if the "
        "two do not share a frame (odometry against GPS, say), --align scores the covariance "
        "after that motion",
        file=sys.stderr,
    )


def _warn_of_one_frame(estimate, covariances, truth, found) -> None:
    """Say why --align made the ANEES far larger: the estimate shares the truth's frame, and
    the rigid motion moved poses whose covariance is all but zero (an exactly known start)
    by the fit's own residual, an error their covariance cannot hold."""
    unmoved = consistency(estimate, covariances, truth, aligned=False)
    if not found.anees > 10.0 * unmoved.anees:
        return
    worst = int(np.nanargmax(found.nees))
    motion = alignment(estimate, truth)
    print(
        f"evaluate: warning: --align makes the ANEES {found.anees:.4g}, against "
        f"{unmoved.anees:.4g} as the trajectory is: it is in the truth's frame already, and "
        "the rigid motion "
        f"(turned {math.degrees(motion[2]):.3g} deg, shifted {math.hypot(*motion[:2]):.3g} m) "
        f"moves poses whose covariance is all but zero (pose {worst}'s NEES is "
        f"{found.nees[worst]:.3g}: an exactly known start); leave --align out",
        file=sys.stderr,
    )


# Files this large take seconds: a terminal is told what is going on (10^6 poses, ~50 MB).
_LARGE_FILE = 20_000_000


def _stage(path: Path, doing: str) -> None:
    """Say on a terminal's standard error what a long evaluation is doing."""
    if not sys.stderr.isatty() or not path.is_file() or path.stat().st_size < _LARGE_FILE:
        return
    print(f"evaluate: {doing} ({path}, {path.stat().st_size / 1e6:.0f} MB)", file=sys.stderr)


def plan_metrics(args) -> dict:
    """A trajectory against a plan (``diffdrive plan`` writes one): cross-track, along-track,
    heading and position errors, the reference at each pose's time (after --t-offset) along
    the arcs between the plan's rows, held at its end once it has ended."""
    if args.input is None or args.truth is not None or args.consistency:
        raise TableError(
            "evaluate --plan measures one trajectory against the plan: give the trajectory, and "
            "neither --truth nor --consistency"
        )
    pairing = {  # options of a comparison with a truth, which a plan's does not use
        "--t-max-diff": args.t_max_diff != 0.01,
        "--interpolate": args.interpolate,
        "--rpe": args.rpe != 1.0,
        "--rpe-unit": args.rpe_unit != "m",
        "--rpe-pairs": args.rpe_pairs != "consecutive",
    }
    refuse_unused(
        pairing,
        "evaluate --plan reads the plan at each pose's time (after --t-offset); it has no "
        "pairs or RPE windows to set",
    )
    plan_times, plan_poses = read_trajectory(args.plan, args.time_unit)
    times, estimate = read_trajectory(args.input, args.time_unit, args.topic)
    for path, poses in ((args.input, estimate), (args.plan, plan_poses)):
        if poses.ndim != 2:
            raise TableError(f"{path}: evaluate takes one robot; the file has {len(poses)}")
    shifted = times + args.t_offset
    if shifted[-1] < plan_times[0] or shifted[0] > plan_times[-1]:
        raise TableError(
            f"{args.input}: its times ({shifted[0]:g} to {shifted[-1]:g} s after --t-offset) "
            f"do not meet the plan's ({plan_times[0]:g} to {plan_times[-1]:g} s)"
        )
    at = np.clip(shifted, plan_times[0], plan_times[-1])
    reference = interpolate(plan_times, plan_poses, at)
    errors = path_errors(plan_times, plan_poses, at, estimate, reference)
    cross = np.abs(errors.cross_track)
    return {
        "poses_compared": len(times),
        "mean_cross_track_m": float(cross.mean()),
        "max_cross_track_m": float(cross.max()),
        "max_along_track_m": float(np.abs(errors.along_track).max()),
        "max_heading_error_deg": float(np.degrees(np.abs(errors.heading).max())),
        "mean_position_error_m": float(errors.position.mean()),
        "max_position_error_m": float(errors.position.max()),
    }


def evaluation_metrics(args, times, estimate, truth) -> dict:
    """The paper's measures, ATE and RPE; a truth without headings (GPS) gives the position
    measures only (the others are None)."""
    # GPS on either side (a NavSatFix topic as the estimate, or as the truth) has no heading.
    positions_only = bool(np.isnan(truth[:, 2]).any() or np.isnan(estimate[:, 2]).any())
    if positions_only:  # compare positions: the headings take no part
        estimate, truth = estimate.copy(), truth.copy()
        estimate[:, 2] = truth[:, 2] = 0.0
    errors = run_errors(estimate, truth)
    metrics = {
        "poses_compared": len(times),
        "max_position_error_m": errors.max_position,
        "final_position_error_m": errors.final_position,
        "max_heading_error_deg": None if positions_only else errors.max_heading,
        "final_heading_error_deg": None if positions_only else errors.final_heading,
        "ate_m": ate(estimate, truth),
        "ate_aligned_m": ate(estimate, truth, aligned=True),
    }
    name = f"rpe_{args.rpe:g}{args.rpe_unit}_{args.rpe_pairs}"
    metrics[f"{name}_m"] = metrics[f"{name}_deg"] = None
    if not positions_only:
        try:
            metrics[f"{name}_m"], metrics[f"{name}_deg"] = rpe(
                estimate, truth, args.rpe, unit=args.rpe_unit, times=times, pairs=args.rpe_pairs
            )
        except ValueError as exc:
            if "no pair of poses" not in str(exc):
                raise
            # A path shorter than the window: the other measures stand; this one is named.
            print(
                f"evaluate: the RPE over {args.rpe:g} {args.rpe_unit} is not computed: {exc} "
                "(a shorter --rpe window, or --rpe-unit poses)",
                file=sys.stderr,
            )
    return metrics


def _paired(args, times, estimate, truth_times, truth, covariances=None):
    """The estimate, the truth and the estimate's covariances (if any) at paired times:
    associated as evo does, or the estimate interpolated along its arcs at the truth's times
    (--interpolate; the covariances linearly, entry by entry)."""
    if args.interpolate:
        shifted = times + args.t_offset
        inside = (truth_times >= shifted[0]) & (truth_times <= shifted[-1])
        if not inside.any():
            raise TableError(f"{args.truth}: no ground-truth time lies within {args.input}'s")
        at = truth_times[inside]
        if covariances is not None:
            covariances = interpolate_covariances(shifted, covariances, at)
        return at, interpolate(shifted, estimate, at), truth[inside], covariances
    i, j = associate(times, truth_times, args.t_max_diff, args.t_offset)
    if len(i) < 2:
        raise TableError(
            f"{args.truth}: {len(i)} of its times are within --t-max-diff {args.t_max_diff} s of "
            f"{args.input}'s (after --t-offset {args.t_offset} s); 2 or more are needed"
        )
    return truth_times[j], estimate[i], truth[j], None if covariances is None else covariances[i]


EPILOGS = {
    "evaluate": f"""examples:
  diffdrive evaluate                       the built-in example's odometry against its truth
  diffdrive evaluate odometry.tum --truth truth.csv --rpe 1.0 --json
  diffdrive evaluate est.tum --truth gt.tum --t-offset -0.003 --rpe 10 --rpe-unit poses
  diffdrive evaluate odometry.csv --truth truth.csv --consistency
  diffdrive evaluate follow.csv --plan plan.csv    against a plan: cross-track, along-track

{TRAJECTORY_FILES} Poses are paired by time as evo pairs them: the nearest
stamp within --t-max-diff s, after adding --t-offset to the trajectory's times;
--interpolate instead samples the trajectory at every ground-truth time along its arcs.""",
}


def add_to(command: Command, parents: Parents) -> None:
    """The options of ``diffdrive evaluate``."""
    ev = command(
        "evaluate",
        "a trajectory against ground truth",
        [parents.times],
        run_evaluate,
        EPILOGS["evaluate"],
    )
    ev.add_argument("input", nargs="?", type=Path, help="trajectory; none: built-in")
    ev.add_argument("--truth", type=Path, help="ground-truth trajectory")
    ev.add_argument(
        "--plan",
        type=Path,
        help="a plan (diffdrive plan writes one) to measure the trajectory against instead: "
        "cross-track, along-track, heading and position errors",
    )
    ev.add_argument(
        "--t-max-diff",
        type=float,
        default=0.01,
        metavar="S",
        help="largest time difference of a pair of poses, s (default 0.01, as evo)",
    )
    ev.add_argument(
        "--t-offset",
        type=float,
        default=0.0,
        metavar="S",
        help="added to the trajectory's times before pairing, s (default 0)",
    )
    ev.add_argument(
        "--interpolate",
        action="store_true",
        help="sample the trajectory at the truth's times along its arcs",
    )
    ev.add_argument("--rpe", type=float, default=1.0, help="RPE window (default 1)")
    ev.add_argument("--rpe-unit", choices=["m", "s", "poses"], default="m")
    ev.add_argument(
        "--rpe-pairs",
        choices=RPE_PAIRS,
        default="consecutive",
        help="consecutive (evo's default) or all (evo's --all_pairs)",
    )
    ev.add_argument(
        "--consistency",
        action="store_true",
        help="also how honest the estimate's covariance is: ANEES (1: honest; below: too "
        "wide; above: too narrow) and the shares inside the 50 %% and 95 %% ellipses; reads "
        "the covariance columns (odometry --covariance) or a bag's Odometry covariances",
    )
    ev.add_argument(
        "--align",
        action="store_true",
        help="with --consistency: move the trajectory onto the truth by the rigid motion that "
        "fits them best first, its covariances turned with it (for frames of their own)",
    )
    add_datum_option(ev)
    ev.add_argument("--json", action="store_true")
