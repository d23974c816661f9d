"""The calibrated robot, its noise model and its drive as the files other stacks take:
ros2_controllers' ``diff_drive_controller`` (``"ros2"``), robot_localization's process noise
(``"robot_localization"``), Nav2 AMCL's alphas (``"amcl"``) and WPILib's drivetrain constants
(``"wpilib"``, JSON), and the C core's configuration for a robot's firmware (``"c-header"``).
``targets`` derives the figures (how each is derived is there and in the
file), ``amcl`` holds Nav2's sampler, ``files`` writes them. ``nav2_mppi`` writes an ``MPPI``
controller's settings as Nav2's MPPI controller reads them.

Before a file is written from runs, ``refusals`` says what the model's own runs show against
it: a model whose predicted covariance holds fewer than 80 % of its runs' poses inside the 95 %
ellipse, or whose wheel noise ``k`` came out at its bound, 0, would put a near-zero covariance
into a filter that then trusts it beyond every other sensor.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from diffdrive.calibration.noise import NoiseModel
from diffdrive.estimation.settings import Encoders
from diffdrive.export.files import FILES, NODES, WPILIB_SCHEMA, render, write
from diffdrive.export.targets import TARGETS, DriveConstants, Reference, amcl_fit, parameters
from diffdrive.model import DiffDrive

__all__ = [
    "FILES",
    "MIN_INSIDE_95",
    "NODES",
    "TARGETS",
    "WPILIB_SCHEMA",
    "DriveConstants",
    "Reference",
    "amcl_fit",
    "export",
    "parameters",
    "refusals",
    "render",
]

MIN_INSIDE_95 = 0.80
"""The least share of the runs' poses inside the model's 95 % ellipse that an export accepts."""


def refusals(found, model: NoiseModel) -> list[str]:
    """Why ``model`` should not be exported, given ``found`` (``evaluation.Consistency`` of its
    predicted covariance on the runs it came from): each reason with its figures; empty when
    there is none."""
    reasons = []
    if found.inside_95 < MIN_INSIDE_95:
        reasons.append(
            f"its covariance holds {found.inside_95:.0%} of the runs' poses inside its 95 % "
            f"ellipse (ANEES {found.anees:.3g}), fewer than {MIN_INSIDE_95:.0%}"
        )
    for wheel in ("k_left", "k_right"):
        if wheel in model.terms and getattr(model, wheel) == 0.0:
            reasons.append(
                f"its wheel noise {wheel} came out at its bound, 0 m: the runs' errors went to "
                "the other terms (a reference less accurate than stated, --reference-sigma?)"
            )
    return reasons


def export(
    target: str,
    robot: DiffDrive,
    nominal: DiffDrive,
    model: NoiseModel,
    path: str | Path,
    at: Reference | None = None,
    notes: Sequence[str] = ("written by diffdrive",),
    *,
    wheel_names: tuple[str, str] | None = None,
    drive: DriveConstants | None = None,
    encoders: Encoders | None = None,
) -> dict[str, object]:
    """Write ``target``'s file to ``path`` (whole or not at all) and return its figures
    (``parameters``; the ``notes`` go at its top)."""
    at = Reference() if at is None else at
    figures = parameters(
        target, robot, nominal, model, at, wheel_names=wheel_names, drive=drive, encoders=encoders
    )
    write(path, render(target, figures, at, list(notes)))
    return figures
