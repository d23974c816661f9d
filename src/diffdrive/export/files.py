"""Each target's file: ROS 2 parameter files (YAML) for the ROS targets, a JSON document for
WPILib (``WPILIB_SCHEMA`` is its JSON schema), written whole or not at all."""

from __future__ import annotations

import json
from pathlib import Path

from diffdrive.atomic import atomic_write
from diffdrive.export.targets import Reference

__all__ = ["FILES", "NODES", "WPILIB_SCHEMA", "render", "write", "yaml_value"]

# The node each ROS file configures, as ``ros2 param load NODE FILE`` and a launch file take it.
NODES = {
    "ros2": "diff_drive_controller",
    "robot_localization": "ekf_filter_node",
    "amcl": "amcl",
}
FILES = {
    "ros2": "diff_drive_controller.yaml",
    "robot_localization": "ekf.yaml",
    "amcl": "amcl.yaml",
    "wpilib": "drivetrain.json",
}
WPILIB_SCHEMA = Path(__file__).with_name("wpilib.schema.json")
# What each WPILib figure is, in the file itself (JSON has no comments).
_WPILIB_UNITS = {
    "trackWidth": "m: DifferentialDriveKinematics' track width (the calibrated, effective one)",
    "stateStdDevs": "m, m, rad: DifferentialDrivePoseEstimator's state standard deviations",
    "kS": "V: SimpleMotorFeedforward's kS (static friction)",
    "kV": "V s/m: kV of the wheels' mean speed (the linear channel)",
    "kA": "V s^2/m: kA of the linear channel",
    "kVAngular": "V s/m: kV of the wheels' speed from turning (identifyDrivetrainSystem)",
    "kAAngular": "V s^2/m: kA of the angular channel",
}


# What each target's figures assume, stated in the file.
_SETTINGS = {
    "ros2": "the pose covariance after {at.distance:g} m straight; the twist's at {at.speed:g} "
    "m/s, the controller updating at {at.rate:g} Hz with a {at.window}-update rolling window",
    "robot_localization": "the process noise per second while driving at {at.speed:g} m/s",
    "amcl": "matched on AMCL's updates at update_min_d and update_min_a, the odometry looked at "
    "with each laser scan at {at.scan_rate:g} Hz, driving at {at.speed:g} m/s and turning in "
    "place at {at.turn_rate:g} rad/s",
    "wpilib": "the state standard deviations after {at.distance:g} m straight",
}


def yaml_value(value: object) -> str:
    """A value as YAML 1.1 and 1.2 both read it (``1.0e-09``: PyYAML reads ``1e-09`` as
    text), integers as integers (a ROS ``int`` parameter refuses a float)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, list):
        return "[" + ", ".join(yaml_value(v) for v in value) + "]"
    if isinstance(value, int) and not isinstance(value, bool):
        return str(value)
    text = repr(float(value))  # type: ignore[arg-type]
    mantissa, _, exponent = text.partition("e")
    if exponent and "." not in mantissa:
        text = f"{mantissa}.0e{exponent}"
    return text


def render(target: str, figures: dict[str, object], at: Reference, notes: list[str]) -> str:
    """The file's text: a ROS 2 parameter file (``node: ros__parameters: ...``) with the
    ``notes`` and the derivation in comments, or for WPILib a JSON document holding them."""
    settings = _SETTINGS[target].format(at=at)
    if target == "wpilib":
        document = {
            "format": "diffdrive.wpilib/1",
            "notes": [*notes, "see diffdrive.export for how each figure is derived", settings],
            "units": {name: _WPILIB_UNITS[name] for name in figures},
            **figures,
        }
        return json.dumps(document, indent=2) + "\n"
    lines = [f"# {note}" for note in notes]
    lines += [f"# {target}: see diffdrive.export for how each figure is derived", f"# {settings}"]
    lines += [f"{NODES[target]}:", "  ros__parameters:"]
    lines += [f"    {name}: {yaml_value(value)}" for name, value in figures.items()]
    return "\n".join(lines) + "\n"


def write(path: str | Path, text: str) -> None:
    """``text`` to ``path``, whole or not at all."""
    with atomic_write(path) as out:
        out.write(text)
