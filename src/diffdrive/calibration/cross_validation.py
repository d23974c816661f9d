"""Cross-validation of a calibration: how accurate the *next* run will be.

Calibrating on some runs and scoring on the same ones rewards fitting their noise. Here the runs
are split into folds: each fold's runs are held out, the robot is calibrated on the others, and
the held-out runs are scored with it (the OptiOdom paper's measures, ``run_errors``). The
schemes: ``"loo"`` (leave one run out), an int ``k`` (k folds over the runs, in order), or an
explicit list of held-out run indices (one fold). A fold whose training runs cannot identify
the parameters is recorded with the reason, never scored with a guessed robot.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import partial

import numpy as np

from diffdrive.calibration.offline import (
    PARAMETERS,
    CalibrationError,
    CalibrationMethod,
    MethodOptions,
    calibrate,
    checked_runs,
    run_names,
)
from diffdrive.evaluation import RunErrors, run_errors, worst
from diffdrive.integrate import Method
from diffdrive.io.run import Run
from diffdrive.model import Robot
from diffdrive.simulation import dead_reckon

__all__ = ["CrossValidation", "Fold", "cross_validate"]


@dataclass(frozen=True, eq=False)
class Fold:
    """One fold: the ``held_out`` run indices, the ``parameters`` fitted on the others (None if
    refused, with the ``refusal``), and each held-out run's ``errors``."""

    held_out: tuple[int, ...]
    parameters: np.ndarray | None
    errors: tuple[RunErrors, ...]
    refusal: str = ""


@dataclass(frozen=True, eq=False)
class CrossValidation:
    """``in_sample``: the worst of each measure over the runs, calibrated on all of them;
    ``held_out``: the worst over the runs scored by the folds that held them out (None when
    every fold was refused); ``folds``; the parameters' mean and standard deviation across
    the folds that fitted, ``(3,)`` over ``PARAMETERS``."""

    in_sample: RunErrors
    held_out: RunErrors | None
    folds: tuple[Fold, ...]

    @property
    def fitted(self) -> np.ndarray:
        """The fitted folds' parameters, ``(n, 3)``."""
        return np.array([f.parameters for f in self.folds if f.parameters is not None])

    @property
    def spread(self) -> np.ndarray:
        """The parameters' standard deviation across the fitted folds (NaN under two)."""
        fitted = self.fitted
        return fitted.std(axis=0, ddof=1) if len(fitted) > 1 else np.full(3, np.nan)

    @property
    def refused(self) -> list[Fold]:
        """The folds whose calibration was refused (``parameters`` None)."""
        return [fold for fold in self.folds if fold.parameters is None]


def _folds(scheme, count: int) -> list[tuple[int, ...]]:
    if scheme == "loo":
        return [(k,) for k in range(count)]
    if isinstance(scheme, int) and not isinstance(scheme, bool):
        if not 2 <= scheme <= count:
            raise ValueError(f"k folds must be from 2 to the {count} runs, got {scheme}")
        return [tuple(int(k) for k in part) for part in np.array_split(np.arange(count), scheme)]
    held = tuple(int(k) for k in scheme)
    if not held or any(not 0 <= k < count for k in held) or len(set(held)) == count:
        raise ValueError(f"held-out runs must be some, not all, of 0..{count - 1}, got {held}")
    return [held]


def cross_validate(
    nominal_robot: Robot,
    runs: Sequence[Run | tuple[np.ndarray, np.ndarray]],
    method: CalibrationMethod = "least_squares",
    scheme: str | int | Sequence[int] = "loo",
    options: MethodOptions | None = None,
    *,
    integration: Method = "exact",
    fixed: tuple[str, ...] = (),
    names: list[str] | None = None,
) -> CrossValidation:
    """Calibrate on all ``runs`` (in-sample) and by ``scheme`` (see the module), as
    ``calibrate(nominal_robot, runs, method, options, integration=, fixed=, names=)`` does;
    ``integration`` also scores the runs."""
    if len(runs) < 2:
        raise CalibrationError("cross-validation needs 2 or more runs: one to fit, one to score")
    names = run_names(runs, names)
    fit_with = partial(calibrate, integration=integration, fixed=fixed)
    runs = checked_runs(runs, names)

    def scored(result, indices):
        """The runs ``indices`` dead-reckoned with a calibration's robot, from each run's
        first reference pose: what its robot file gives (a fitted heading offset belongs to
        the reference, and the file does not carry it)."""
        return tuple(
            run_errors(
                dead_reckon(result.robot, runs[k][0], runs[k][1][0], integration), runs[k][1]
            )
            for k in indices
        )

    everything = fit_with(nominal_robot, runs, method, options, names=names)
    in_sample = worst(list(scored(everything, range(len(runs)))))
    folds = []
    for held in _folds(scheme, len(runs)):
        train = [k for k in range(len(runs)) if k not in held]
        try:
            fit = fit_with(
                nominal_robot,
                [runs[k] for k in train],
                method,
                options,
                names=[names[k] for k in train],
            )
        except CalibrationError as refusal:
            folds.append(Fold(held, None, (), str(refusal)))
            continue
        parameters = np.array([getattr(fit.robot, name) for name in PARAMETERS])
        folds.append(Fold(held, parameters, scored(fit, held)))
    held_errors = [e for fold in folds for e in fold.errors]
    return CrossValidation(in_sample, worst(held_errors) if held_errors else None, tuple(folds))
