"""The figures of each target's file, from the calibrated robot, its noise model and its drive.

How each figure is derived (``Reference`` holds the choices, all stated in the file):

- ``"ros2"``, ros2_controllers' ``diff_drive_controller``: ``wheel_separation`` and
  ``wheel_radius`` (the nominal robot's) with the multipliers that make them the calibrated
  ones; ``left_wheel_names`` and ``right_wheel_names``; ``velocity_rolling_window_size``; the
  pose covariance diagonal, the noise model's after ``distance`` m straight (the controller
  publishes one constant matrix, so it is the model's at one distance); the twist covariance
  diagonal of the velocity the controller publishes: the mean of the per-update velocities
  over its rolling window of ``window`` updates at ``rate`` Hz, each from the wheels' travel
  over one period (``k |travel|`` each), so ``var(v) = k v rate / (2 window) + (v
  radius_sigma)^2 / 2`` and ``var(w) = 2 k v rate / (window T^2) + 2 (v radius_sigma /
  T)^2`` at ``speed`` (the radius error does not average out);
- ``"robot_localization"``: the ``process_noise_covariance`` of its ``ekf_node``: the
  variance per second of x, y (``k speed / 2`` plus the radius error's) and yaw (``2 k speed
  / T^2``) when driving at ``speed``; the other entries its documented defaults;
- ``"amcl"``: Nav2 AMCL's ``alpha1`` to ``alpha4`` matched to its differential sampler as
  written, updating at the ``update_min_d`` and ``update_min_a`` written beside them
  (``diffdrive.export.amcl``);
- ``"wpilib"``: the track width (the calibrated, effective one), the ``stateStdDevs`` of
  ``DifferentialDrivePoseEstimator`` (the standard deviations after ``distance`` m straight:
  how far the odometry is trusted between measurements) and, from a drive identification,
  kS, kV, kA in WPILib's units (V, V s/m, V s^2/m) and the angular channel's kV, kA.

Unused axes of a 2-D robot (z, roll, pitch) get 1e6 (unknown), and a variance below 1e-9
(its sideways velocity, known zero) gets 1e-9: the covariances ``diffdrive.io.ros.covariance``
states for the bags too, positive definite as the consumers that invert them need.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from diffdrive._validate import finite, positive, whole
from diffdrive.calibration.noise import NoiseModel, covariances
from diffdrive.estimation.fusion import core_settings, start_state
from diffdrive.estimation.settings import Encoders, EstimatorSettings
from diffdrive.export.amcl import match_alphas, reference_motions
from diffdrive.io.ros.covariance import UNESTIMATED, floored
from diffdrive.model import DiffDrive, geometry_of
from diffdrive.sensor_noise import WheelNoise

__all__ = ["TARGETS", "DriveConstants", "Reference", "parameters"]

TARGETS = ("ros2", "robot_localization", "amcl", "wpilib", "c-header")
"""What ``export`` writes for: ROS 2's diff_drive_controller, robot_localization, AMCL, WPILib, and
the C core's header."""
# robot_localization's documented default process noise diagonal (ekf.yaml).
_RL_DEFAULT = (
    0.05,
    0.05,
    0.06,
    0.03,
    0.03,
    0.06,
    0.025,
    0.025,
    0.04,
    0.01,
    0.01,
    0.02,
    0.01,
    0.01,
    0.015,
)


@dataclass(frozen=True)
class Reference:
    """The motions and settings the figures are taken at: ``distance`` m straight, a turn in
    place of ``turn`` rad at ``turn_rate`` rad/s, ``speed`` m/s; the controller's update
    ``rate`` (Hz) and rolling ``window`` (updates, diff_drive_controller's
    ``velocity_rolling_window_size``); AMCL's ``scan_rate`` (Hz, when it checks the
    odometry), ``update_min_d`` (m) and ``update_min_a`` (rad), its defaults."""

    distance: float = 1.0
    turn: float = 1.0
    speed: float = 0.5
    turn_rate: float = 1.0
    rate: float = 50.0
    window: int = 10
    scan_rate: float = 10.0
    update_min_d: float = 0.25
    update_min_a: float = 0.2

    def __post_init__(self) -> None:
        for name in ("distance", "turn", "speed", "turn_rate", "rate", "scan_rate"):
            positive(name, getattr(self, name))
        for name in ("update_min_d", "update_min_a"):
            if not finite(name, getattr(self, name)) >= 0.0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)!r}")
        object.__setattr__(self, "window", whole("window", self.window, 1))


@dataclass(frozen=True)
class DriveConstants:
    """A drivetrain's feedforward in WPILib's units: ``ks`` (V), ``kv`` (V s/m), ``ka`` (V
    s^2/m) of the wheels' mean (the linear channel) and, if identified, the angular channel's
    ``kv_angular`` and ``ka_angular`` (V s/m, V s^2/m of the wheels' speed from turning), as
    ``LinearSystemId.identifyDrivetrainSystem`` takes them."""

    ks: float
    kv: float
    ka: float
    kv_angular: float | None = None
    ka_angular: float | None = None

    def __post_init__(self) -> None:
        for name in ("ks", "kv", "ka", "kv_angular", "ka_angular"):
            value = getattr(self, name)
            if value is not None:
                finite(name, value)


def _motion_covariance(robot: DiffDrive, model: NoiseModel, increments: np.ndarray):
    """The model's covariance (reference terms left out) after wheel-angle ``increments``
    ``(S, 2)`` rad from the origin."""
    quiet = replace(model, reference_sigma=0.0, reference_heading_sigma=0.0)
    return covariances(robot, increments, np.zeros(3), quiet)[1][-1]


def _straight(robot: DiffDrive, distance: float) -> np.ndarray:
    left, right = distance / robot.left_wheel_radius, distance / robot.right_wheel_radius
    return np.tile([left / 100, right / 100], (100, 1))


def parameters(
    target: str,
    robot: DiffDrive,
    nominal: DiffDrive,
    model: NoiseModel,
    at: Reference,
    *,
    wheel_names: tuple[str, str] | None = None,
    drive: DriveConstants | None = None,
    encoders: Encoders | None = None,
) -> dict[str, object]:
    """The figures of ``target`` for the calibrated ``robot`` (the ``nominal`` one gives the
    base values ROS multiplies), as a dict: see the module. ``wheel_names`` (left, right) are
    the ROS 2 controller's joints; ``drive`` WPILib's feedforward; ``encoders`` the
    firmware's (``"c-header"``)."""
    if target not in TARGETS:
        raise ValueError(f"target must be one of {', '.join(TARGETS)}, got {target!r}")
    for name, value, kind in (
        ("robot", robot, DiffDrive),
        ("nominal", nominal, DiffDrive),
        ("model", model, NoiseModel),
        ("at", at, Reference),
    ):
        if not isinstance(value, kind):
            raise TypeError(f"{name} must be a {kind.__name__}, got {type(value).__name__}")
    if wheel_names is not None and (
        not isinstance(wheel_names, tuple | list)
        or len(wheel_names) != 2
        or not all(isinstance(name, str) and name for name in wheel_names)
    ):
        raise TypeError(f"wheel_names must be two joint names (left, right), got {wheel_names!r}")
    # NoiseModel refuses a negative or non-finite term; all three 0 is its own mistake here.
    if not any((model.k, model.radius_sigma, model.track_sigma)):
        # Zero covariances read as perfectly known (a filter then ignores every other sensor)
        # or as unset: the mistake these files are written to end (turtlebot3#1069).
        raise ValueError(
            "the noise model has no wheel noise (k, radius_sigma and track_sigma all 0): every "
            "covariance would be zero; identify it from runs or give a term > 0"
        )
    if target == "ros2":
        return _ros2(robot, nominal, model, at, wheel_names)
    if target == "amcl":
        return _amcl(robot, model, at)
    if target == "c-header":
        return _c_header(robot, model, encoders)
    k, track = model.k, robot.track_width
    if target == "robot_localization":
        diagonal = list(_RL_DEFAULT)
        diagonal[0] = diagonal[1] = k * at.speed / 2 + at.speed**2 * _speed_share(model)
        diagonal[5] = 2 * k * at.speed / track**2
        return {"process_noise_covariance": np.diag(diagonal).ravel().tolist()}
    straight = _motion_covariance(robot, model, _straight(robot, at.distance))
    figures: dict[str, object] = {
        "trackWidth": track,
        "stateStdDevs": np.sqrt(np.diag(straight)).tolist(),
    }
    if drive is not None:
        figures.update(kS=drive.ks, kV=drive.kv, kA=drive.ka)
        if drive.kv_angular is not None and drive.ka_angular is not None:
            figures.update(kVAngular=drive.kv_angular, kAAngular=drive.ka_angular)
    return figures


def _ros2(robot, nominal, model, at, wheel_names) -> dict[str, object]:
    if wheel_names is None:
        raise ValueError(
            "diff_drive_controller needs left_wheel_names and right_wheel_names: give the "
            "wheels' joint names"
        )
    straight = _motion_covariance(robot, model, _straight(robot, at.distance))
    k, track, v = model.k, robot.track_width, at.speed
    # The published velocity: the mean over the window of each update's travel over its
    # period, so the travel's noise averages over window updates; a radius error does not.
    var_v = k * v * at.rate / (2 * at.window) + v**2 * _speed_share(model)
    geometry = model.geometry
    turned = geometry[0, 0] + geometry[1, 1] - 2 * geometry[0, 1]
    var_w = 2 * k * v * at.rate / (at.window * track**2) + (v / track) ** 2 * turned
    base = nominal.left_wheel_radius
    return {
        "left_wheel_names": [wheel_names[0]],
        "right_wheel_names": [wheel_names[1]],
        "wheel_separation": nominal.track_width,
        "wheel_radius": base,
        "wheel_separation_multiplier": track / nominal.track_width,
        "left_wheel_radius_multiplier": robot.left_wheel_radius / base,
        "right_wheel_radius_multiplier": robot.right_wheel_radius / base,
        "velocity_rolling_window_size": at.window,
        "pose_covariance_diagonal": _ros_diagonal(np.diag(straight)),
        "twist_covariance_diagonal": _ros_diagonal([var_v, 0.0, var_w]),
    }


def _ros_diagonal(planar: object) -> list[float]:
    """Variances of x, y, yaw (or their rates) as ROS's diagonal of six: each at least
    ``covariance.FLOOR``, the axes a planar robot does not estimate unknown."""
    x, y, yaw = np.diag(floored(np.diag(np.asarray(planar, dtype=float)))).tolist()
    return [x, y, UNESTIMATED, UNESTIMATED, UNESTIMATED, yaw]


def _c_header(robot: DiffDrive, model: NoiseModel, encoders: Encoders | None):
    """The C core's ``dd_odometry_config`` and ``dd_filter_config`` fields, in its order."""
    if encoders is None or encoders.ticks_per_revolution is None or not encoders.counter_bits:
        raise ValueError(
            "the C core converts counter readings itself: give the encoders' counts per wheel "
            "revolution and their counters' width in bits (a count that never rolls over: 64)"
        )
    noise = WheelNoise(model.k_left, model.k_right)
    settings = EstimatorSettings(heading="fused", wheel_noise=noise)
    core = core_settings(robot, settings, *start_state(robot, settings, None, None))
    r_left, r_right, track, offset = geometry_of(robot)
    odometry: dict[str, object] = {
        "drive": [r_left, r_right, track, offset],
        "method": "DD_EXACT",
        "ticks_per_revolution": encoders.ticks_per_revolution,
        "counter_bits": encoders.counter_bits,
        "max_wheel_speed": encoders.max_wheel_speed or math.inf,
        "k_left": noise.left,
        "k_right": noise.right,
    }
    filtered: dict[str, object] = {
        "drive": [r_left, r_right, track, offset],
        "method": "DD_EXACT",
        "heading": "DD_FROM_BOTH",
        "estimate_bias": int(core.estimate_bias),
        "estimate_scale": int(core.estimate_scale),
        "estimate_distance": int(core.estimate_distance),
        "estimate_offset": int(core.estimate_offset),
        "k_left": noise.left,
        "k_right": noise.right,
        "wheel_floor": encoders.wheel_floor,
        "arw2": core.arw2,
        "rrw2": core.rrw2,
        "offset_rate2": core.offset_rate2,
        "slip_threshold": core.slip_threshold,
        "slip_inflation": core.slip_inflation,
        "gates": list(core.gates),
        "inflate": int(core.inflate),
        "reference_offset": core.offset,
    }
    return {"odometry": odometry, "filter": filtered}


def _speed_share(model: NoiseModel) -> float:
    """The relative variance of a straight's speed from the radii's errors: a quarter of
    their sum's (the radii move together where the model says they do)."""
    geometry = model.geometry
    return float(geometry[0, 0] + geometry[1, 1] + 2 * geometry[0, 1]) / 4


def _amcl(robot, model, at) -> dict[str, object]:
    fit = amcl_fit(robot, model, at)
    figures: dict[str, object] = {"robot_model_type": "nav2_amcl::DifferentialMotionModel"}
    figures.update({f"alpha{i + 1}": float(alpha) for i, alpha in enumerate(fit.alphas)})
    figures.update(update_min_d=at.update_min_d, update_min_a=at.update_min_a)
    return figures


def amcl_fit(robot: DiffDrive, model: NoiseModel, at: Reference):
    """AMCL's alphas matched to the noise model on the reference motions (an ``AlphaFit``)."""
    motions = reference_motions(robot, at)
    targets = np.array([_motion_covariance(robot, model, m.increments) for m in motions])
    return match_alphas(motions, targets)
