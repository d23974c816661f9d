"""``diffdrive evaluate``: a trajectory against ground truth."""

from __future__ import annotations

import argparse
import json

import numpy as np

from diffdrive import sources
from diffdrive.calibration import odometry_of
from diffdrive.evaluation import associate, ate, interpolate, rpe, run_errors
from diffdrive.examples import (
    example_log,
    example_robot,
)
from diffdrive.files import TableError


def run_evaluate(args: argparse.Namespace) -> int:
    if args.input is None:
        log, robot = example_log(), example_robot()
        times, truth = log.times, log.truth
        estimate = odometry_of(robot, log.increments(), truth[0], "exact")
    else:
        if args.truth is None:
            raise TableError("evaluate needs --truth with a ground-truth trajectory or bag")
        times, estimate = sources.trajectory(args.input, args.time_unit, args.topic)
        truth_times, truth = sources.trajectory(args.truth, args.time_unit, args.truth_topic)
        for path, poses in ((args.input, estimate), (args.truth, truth)):
            if poses.ndim != 2:
                raise TableError(f"{path}: evaluate takes one robot; the file has {len(poses)}")
        times, estimate, truth = _paired(args, times, estimate, truth_times, truth)
    metrics = evaluation_metrics(args, times, estimate, truth)
    if args.json:
        print(json.dumps(metrics))
    else:
        for key, value in metrics.items():
            shown = "n/a" if value is None else (f"{value:.6f}" if isinstance(value, float)
                                                 else str(value))  # fmt: skip
            print(f"{key:34} {shown:>12}")
    return 0


def evaluation_metrics(args, times, estimate, truth) -> dict:
    """The paper's measures, ATE and RPE; a truth without headings (GPS) gives the position
    measures only (the others are None)."""
    positions_only = bool(np.isnan(truth[:, 2]).any())
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
        metrics[f"{name}_m"], metrics[f"{name}_deg"] = rpe(
            estimate, truth, args.rpe, unit=args.rpe_unit, times=times, pairs=args.rpe_pairs
        )
    return metrics


def _paired(args, times, estimate, truth_times, truth):
    """The estimate and the truth at paired times: associated as evo does, or the estimate
    interpolated along its arcs at the truth's times (--interpolate)."""
    if args.interpolate:
        shifted = times + args.t_offset
        inside = (truth_times >= shifted[0]) & (truth_times <= shifted[-1])
        if not inside.any():
            raise TableError(f"{args.truth}: no ground-truth time lies within {args.input}'s")
        at = truth_times[inside]
        return at, interpolate(shifted, estimate, at), truth[inside]
    i, j = associate(times, truth_times, args.t_max_diff, args.t_offset)
    if len(i) < 2:
        raise TableError(
            f"{args.truth}: {len(i)} of its times are within --t-max-diff {args.t_max_diff} s of "
            f"{args.input}'s (after --t-offset {args.t_offset} s); 2 or more are needed"
        )
    return truth_times[j], estimate[i], truth[j]
