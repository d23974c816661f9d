"""Each target's file: ROS 2 parameter files (YAML) for the ROS targets, a JSON document for
WPILib (``WPILIB_SCHEMA`` is its JSON schema), a C header for the C core's firmware, written
whole or not at all."""

from __future__ import annotations

import json
import math
from pathlib import Path

from diffdrive.atomic import atomic_write
from diffdrive.export.targets import Reference

__all__ = ["FILES", "NODES", "WPILIB_SCHEMA", "render", "write", "yaml_value"]

NODES = {
    "ros2": "diff_drive_controller",
    "robot_localization": "ekf_filter_node",
    "amcl": "amcl",
}
"""The node each ROS file configures, by target, as ``ros2 param load NODE FILE`` and a launch file
take it."""
FILES = {
    "ros2": "diff_drive_controller.yaml",
    "robot_localization": "ekf.yaml",
    "amcl": "amcl.yaml",
    "wpilib": "drivetrain.json",
    "c-header": "diffdrive_robot.h",
}
"""The file each target writes by default, by target."""
WPILIB_SCHEMA = Path(__file__).with_name("wpilib.schema.json")
"""The JSON Schema of the WPILib file, which the export checks what it writes against."""
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
    "c-header": "the calibrated equivalent drive and wheel noise; the filter's gyro noise, "
    "gates and slip test are diffdrive's defaults (EstimatorSettings) for a heading fused from "
    "wheels and gyro: replace them with your gyro's",
}
# What each field of the C core's configurations is (c/include/diffdrive/*.h say more).
_C_FIELDS = {
    "drive": "r_left, r_right, track, offset: m (the equivalent drive)",
    "method": "the step: the exact arc (SE(2) exponential)",
    "ticks_per_revolution": "encoder counts per wheel revolution",
    "counter_bits": "the counters' width: a change of more than half their range is a roll-over",
    "max_wheel_speed": "rad/s past which a reading is refused (INFINITY: none)",
    "k_left": "m: the left wheel's travel variance per metre travelled",
    "k_right": "m: the right wheel's",
    "wheel_floor": "rad^2: a wheel angle increment's least variance, its counts' rounding",
    "heading": "from the wheels' turn and the gyro's, fused",
    "estimate_bias": "the gyro's bias estimated",
    "estimate_scale": "the turn scale estimated",
    "estimate_distance": "the distance scale estimated",
    "estimate_offset": "the position fixes' offset estimated",
    "arw2": "rad^2/s: the gyro's angle random walk, squared",
    "rrw2": "(rad/s)^2/s: its bias's random walk, squared",
    "offset_rate2": "m^2/s: the fixes' offset's random walk, squared",
    "slip_threshold": "the slip test's chi-square threshold",
    "slip_inflation": "a slipping interval's wheel noise grows by this",
    "gates": "chi-square gates for measurements of 1, 2 and 3 values",
    "inflate": "past the gate: 1 inflates the measurement's covariance, 0 refuses it",
    "reference_offset": "m: the state's reference point left of the body origin",
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
    if target == "c-header":
        return _c_header(figures, [*notes, settings])
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


def _c_value(value: object) -> str:
    """A figure as a C initialiser: a name or integer as it is, a double to the last digit
    (a float build rounds it once, at compile time), infinity as INFINITY (math.h)."""
    if isinstance(value, str | int) and not isinstance(value, bool):
        return str(value)
    if isinstance(value, list):
        return "{" + ", ".join(_c_value(v) for v in value) + "}"
    number = float(value)  # type: ignore[arg-type]
    if math.isinf(number):
        return "INFINITY" if number > 0 else "-INFINITY"
    text = repr(number)
    return text if any(mark in text for mark in ".en") else text + ".0"


def _c_header(figures: dict[str, object], notes: list[str]) -> str:
    """The header: the notes, then ``diffdrive_odometry`` and ``diffdrive_filter``, the C
    core's configurations, each field commented."""
    notes = [*notes, "see diffdrive.export for how each figure is derived"]
    lines = ["/* " + "\n * ".join(notes) + " */"]
    lines += [
        "#ifndef DIFFDRIVE_ROBOT_H",
        "#define DIFFDRIVE_ROBOT_H",
        "",
        "#include <math.h>",
        "",
        '#include "diffdrive/filter.h"',
        '#include "diffdrive/odometry.h"',
    ]
    for name, kind in (("odometry", "dd_odometry_config"), ("filter", "dd_filter_config")):
        fields = figures[name]
        assert isinstance(fields, dict)
        lines += ["", f"static const {kind} diffdrive_{name} = {{"]
        for field, value in fields.items():
            lines.append(f"    .{field} = {_c_value(value)}, /* {_C_FIELDS[field]} */")
        lines.append("};")
    lines += ["", "#endif"]
    return "\n".join(lines) + "\n"


def write(path: str | Path, text: str) -> None:
    """``text`` to ``path``, whole or not at all."""
    with atomic_write(path) as out:
        out.write(text)
