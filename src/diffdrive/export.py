"""The calibrated robot and its noise model as the parameter files other stacks take.

- ``"ros2"``: ros2_controllers' ``diff_drive_controller``: ``wheel_separation`` and
  ``wheel_radius`` (the nominal robot's), the multipliers that turn them into the calibrated
  ones (``wheel_separation_multiplier``, ``left_wheel_radius_multiplier``,
  ``right_wheel_radius_multiplier``), and the constant ``pose_covariance_diagonal`` and
  ``twist_covariance_diagonal`` it publishes.
- ``"robot_localization"``: the ``process_noise_covariance`` of its ``ekf_node`` (15 x 15,
  row by row).
- ``"amcl"``: Nav2 AMCL's ``alpha1`` to ``alpha4`` for ``nav2_amcl::DifferentialMotionModel``.
- ``"wpilib"``: the ``stateStdDevs`` of WPILib's ``DifferentialDrivePoseEstimator``.

How each figure is derived (``Reference`` holds the choices, all stated in the file):

- the pose covariance diagonal: the covariance the noise model predicts after driving
  ``distance`` m straight ahead (``noise.covariances`` without the reference's terms): ROS's
  odometry publishes one constant matrix, so it is the model's at one distance;
- the twist covariance diagonal: over one publishing period ``1 / rate`` s at ``speed`` m/s,
  the variance of the wheels' travel (``k |travel|`` each) over the period squared, plus a
  speed scaled by a radius error (``radius_sigma``): ``var(v) = k v rate / 2 + (v
  radius_sigma)^2 / 2``, ``var(w) = 2 k v rate / T^2 + 2 (v radius_sigma / T)^2``;
- robot_localization: the variance per second of x, y (``k speed / 2``) and yaw (``2 k speed
  / T^2``) when driving at ``speed``; the other entries its documented defaults;
- AMCL (variances linear in the squared motion): matched to the model's variances of a
  straight ``distance`` and a turn in place of ``turn`` rad: ``alpha3`` (translation from
  translation) and ``alpha2`` (rotation from translation) from the straight, ``alpha1``
  (rotation from rotation) and ``alpha4`` (translation from rotation) from the turn;
- WPILib: the standard deviations after ``distance`` m straight (its state standard
  deviations say how far the odometry is trusted between measurements).

Unused axes of a 2-D robot (z, roll, pitch) get 1e6 (unknown), its sideways velocity 1e-9
(known zero; some consumers invert the matrix).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from diffdrive._validate import positive
from diffdrive.atomic import atomic_write
from diffdrive.model import DiffDrive
from diffdrive.noise import NoiseModel, covariances

__all__ = ["TARGETS", "Reference", "export", "parameters", "render"]

TARGETS = ("ros2", "robot_localization", "amcl", "wpilib")
UNKNOWN, KNOWN_ZERO = 1e6, 1e-9
# robot_localization's documented default process noise diagonal (ekf.yaml).
_RL_DEFAULT = (0.05, 0.05, 0.06, 0.03, 0.03, 0.06, 0.025, 0.025, 0.04, 0.01, 0.01, 0.02, 0.01,
               0.01, 0.015)  # fmt: skip


@dataclass(frozen=True)
class Reference:
    """The motions the figures are taken at: ``distance`` m straight, a turn in place of
    ``turn`` rad, ``speed`` m/s and a publishing ``rate`` Hz."""

    distance: float = 1.0
    turn: float = 1.0
    speed: float = 0.5
    rate: float = 50.0

    def __post_init__(self) -> None:
        for name in ("distance", "turn", "speed", "rate"):
            positive(name, getattr(self, name))


def _motion_covariance(robot: DiffDrive, model: NoiseModel, left: float, right: float):
    """The model's covariance (reference terms left out) after wheel turns ``left``,
    ``right`` (rad) in 100 even steps, from the origin."""
    quiet = replace(model, reference_sigma=0.0, reference_heading_sigma=0.0)
    steps = np.tile([left / 100, right / 100], (100, 1))
    return covariances(robot, steps, np.zeros(3), quiet)[1][-1]


def parameters(
    target: str, robot: DiffDrive, nominal: DiffDrive, model: NoiseModel, at: Reference
) -> dict[str, object]:
    """The figures of ``target`` for the calibrated ``robot`` (the ``nominal`` one gives the
    base values ROS multiplies), as a dict."""
    if target not in TARGETS:
        raise ValueError(f"target must be one of {', '.join(TARGETS)}, got {target!r}")
    # NoiseModel refuses a negative or non-finite term; all three 0 is its own mistake here.
    if not any((model.k, model.radius_sigma, model.track_sigma)):
        # Zero covariances read as perfectly known (a filter then ignores every other sensor)
        # or as unset: the mistake these files are written to end (turtlebot3#1069).
        raise ValueError(
            "the noise model has no wheel noise (k, radius_sigma and track_sigma all 0): every "
            "covariance would be zero; identify it from runs or give a term > 0"
        )
    r_l, r_r, track = robot.left_wheel_radius, robot.right_wheel_radius, robot.track_width
    straight = _motion_covariance(robot, model, at.distance / r_l, at.distance / r_r)
    half = 0.5 * track * at.turn
    spin = _motion_covariance(robot, model, -half / r_l, half / r_r)
    k, sigma = model.k, model.radius_sigma
    if target == "ros2":
        v = at.speed
        var_v = k * v * at.rate / 2 + (v * sigma) ** 2 / 2
        var_w = 2 * k * v * at.rate / track**2 + 2 * (v * sigma / track) ** 2
        base = nominal.left_wheel_radius
        return {
            "wheel_separation": nominal.track_width,
            "wheel_radius": base,
            "wheel_separation_multiplier": track / nominal.track_width,
            "left_wheel_radius_multiplier": r_l / base,
            "right_wheel_radius_multiplier": r_r / base,
            "pose_covariance_diagonal": [
                straight[0, 0], straight[1, 1], UNKNOWN, UNKNOWN, UNKNOWN, straight[2, 2]
            ],
            "twist_covariance_diagonal": [var_v, KNOWN_ZERO, UNKNOWN, UNKNOWN, UNKNOWN, var_w],
        }  # fmt: skip
    if target == "robot_localization":
        diagonal = list(_RL_DEFAULT)
        diagonal[0] = diagonal[1] = k * at.speed / 2 + (at.speed * sigma) ** 2 / 2
        diagonal[5] = 2 * k * at.speed / track**2
        matrix = np.diag(diagonal)
        return {"process_noise_covariance": matrix.ravel().tolist()}
    if target == "amcl":
        d, turn = at.distance, at.turn
        return {
            "robot_model_type": "nav2_amcl::DifferentialMotionModel",
            "alpha1": spin[2, 2] / turn**2,
            "alpha2": straight[2, 2] / d**2,
            "alpha3": straight[0, 0] / d**2,
            "alpha4": (spin[0, 0] + spin[1, 1]) / turn**2,
        }
    spread = np.sqrt(np.diag(straight))
    return {"stateStdDevs": spread.tolist()}


_NODES = {
    "ros2": "diff_drive_controller",
    "robot_localization": "ekf_filter_node",
    "amcl": "amcl",
    "wpilib": "DifferentialDrivePoseEstimator",
}


def _value(value: object) -> str:
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, list):
        return "[" + ", ".join(_value(v) for v in value) + "]"
    text = repr(float(value))  # type: ignore[arg-type]
    mantissa, _, exponent = text.partition("e")
    if exponent and "." not in mantissa:  # YAML 1.1 (PyYAML, libyaml) reads 1e-09 as text
        text = f"{mantissa}.0e{exponent}"
    return text


def render(target: str, figures: dict[str, object], at: Reference, note: str) -> str:
    """The file's text: a ROS 2 parameter file (``node: ros__parameters: ...``) for the ROS
    targets, a YAML mapping for WPILib, with the derivation in comments."""
    lines = [f"# {note}", f"# {target}: see diffdrive.export for how each figure is derived"]
    lines.append(
        f"# at {at.distance:g} m straight, a {at.turn:g} rad turn, {at.speed:g} m/s, {at.rate:g} Hz"
    )
    if target == "wpilib":
        lines.append(f"{_NODES[target]}:")
        indent = "  "
    else:
        lines += [f"{_NODES[target]}:", "  ros__parameters:"]
        indent = "    "
    lines += [f"{indent}{name}: {_value(value)}" for name, value in figures.items()]
    return "\n".join(lines) + "\n"


def export(
    target: str,
    robot: DiffDrive,
    nominal: DiffDrive,
    model: NoiseModel,
    path: str | Path,
    at: Reference | None = None,
    note: str = "written by diffdrive",
) -> dict[str, object]:
    """Write ``target``'s parameter file to ``path`` (atomically) and return its figures."""
    at = Reference() if at is None else at
    figures = parameters(target, robot, nominal, model, at)
    with atomic_write(path) as out:
        out.write(render(target, figures, at, note))
    return figures
