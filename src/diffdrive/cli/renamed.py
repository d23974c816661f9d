"""The command line's spellings before 0.9, kept working for one release: rewritten to
today's before parsing, each with a one-line note on standard error.

0.9 gave each job its own subcommand and each subcommand at most 30 options: ``odometry``
with measurements or ``--smooth`` became ``estimate``; ``calibrate --track-from-gyro`` became
``calibrate-gyro`` and ``calibrate --gps-topic|--pose-topic`` ``calibrate-driving``;
``follow --tracker mppi`` became ``mppi``; ``export --to TARGET`` became ``export TARGET``.
Options that came in pairs or threes became one (``--frames``, ``--joints``, ``--k``,
``--feedforward``, ``--obstacles``), the rarer robot settings ``--robot KEY=VALUE``, the
synthetic gyro's and pose sensor's figures ``--gyro`` and ``--pose``, and the estimator's
tuning ``--settings``. Every angle the command line takes is in radians: ``--imu-rpy`` (degrees)
became ``--imu-mount`` and ``--reference-sigma`` (its heading in degrees) ``--reference-noise``,
their values converted here. This module goes in the next release."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

from diffdrive.cli.synth import GYRO_KEYS, POSE_KEYS
from diffdrive.io.robots import ROBOT_KEYS

# The robot settings that lost their flags: --robot KEY=VALUE.
GEOMETRY = tuple(key for key in ROBOT_KEYS if key not in ("wheel_radius", "track_width"))
# Old odometry options that meant the estimator: with any of them, odometry is estimate.
ESTIMATOR_FLAGS = (
    "--pose-topic",
    "--gps-topic",
    "--measurements",
    "--smooth",
    "--turn-scale-sigma",
    "--gate",
    "--fixes",
    "--pose-sigma",
    "--gps-sigma",
    "--lever-arm",
    "--datum",
)
# Old flags that became one of today's: (today's flag, the old ones in its order, their
# defaults where one may be left out, else None).
GROUPS: dict[str, tuple[tuple[str, ...], tuple[str, ...] | None]] = {
    "--frames": (("--frame", "--child-frame"), ("odom", "base_link")),
    "--joints": (("--left-joint", "--right-joint"), None),
    "--k": (("--k-left", "--k-right"), None),
    "--feedforward": (("--ks", "--kv", "--ka"), None),
    "--obstacles": (("--map", "--footprint"), None),
}
GROUPS_OLD = {old for olds, _ in GROUPS.values() for old in olds}
# synth's figures that became --gyro KEY=VALUE and --pose KEY=VALUE (--gyro-arw: arw).
SYNTH = {f"--gyro-{key}": ("--gyro", key) for key in GYRO_KEYS} | {
    f"--pose-{key}": ("--pose", key) for key in POSE_KEYS
}
# odometry's gyro and output options that the estimator takes as --settings, or always does.
ESTIMATE = {
    "--heading": "heading",
    "--gyro-bias": "bias",
    "--slip-test": "whole_log.slip_episodes",
    "--gate": "gate.probability",
    "--turn-scale-sigma": "turn_scale.sigma",
    "--method": "method",
}
# Options that took angles in degrees, renamed when they went to radians: today's name, how
# many values they take at most, and which of them are angles.
DEGREES = {
    "--imu-rpy": ("--imu-mount", 3, (0, 1, 2)),
    "--reference-sigma": ("--reference-noise", 2, (1,)),
}
ALWAYS = ("--twist", "--covariance")  # estimate writes the twist and covariance always
SWITCHES = ("--twist", "--covariance", "--track-from-gyro", "--smooth")
LATER = "the old spelling goes in the next release"


class MisspelledError(ValueError):
    """An old spelling that has no one meaning today (one of a pair that now goes together)."""


@dataclass
class Rewritten:
    """An argument list in today's spellings (``argv``) and a note for each old one."""

    argv: list[str]
    notes: list[str] = field(default_factory=list)


def today(argv: list[str], options_of: Callable[[str], Mapping[str, object]]) -> Rewritten:
    """``argv`` with the spellings of before 0.9 rewritten to today's. ``options_of(command)``:
    the option strings today's ``command`` knows, each with its ``nargs`` (an old spelling it
    still knows is left as it is, and an old pair is made one only where the command takes
    that one with as many values). ``MisspelledError`` names what cannot be rewritten."""
    if not argv or argv[0].startswith("-"):
        return Rewritten(list(argv))
    command, rest = argv[0], _split_equals(argv[1:])
    notes: list[str] = []
    new_command = _command(command, rest)
    if new_command != command:
        notes.append(f'"{command}" {_why_moved(command, rest)} is now "{new_command}"; {LATER}')
    known = options_of(new_command)
    rest = _in_radians(rest, notes)
    kept, added = _rewrite(new_command, rest, known, notes, moved=new_command != command)
    if new_command == "estimate" and not {"-o", "--output"} & set(rest):
        added += ["-o", "odometry.csv"]  # odometry's default name, which scripts may read
    return Rewritten([*new_command.split(), *kept, *added], notes)


def _in_radians(tokens: list[str], notes: list[str]) -> list[str]:
    """``tokens`` with each option that took degrees (``DEGREES``) under today's name, its
    angles converted to radians; what is no number is left for the parser to refuse."""
    out: list[str] = []
    index = 0
    while index < len(tokens):
        token = tokens[index]
        index += 1
        if token not in DEGREES:
            out.append(token)
            continue
        flag, most, angles = DEGREES[token]
        values: list[str] = []
        while index < len(tokens) and len(values) < most and _is_number(tokens[index]):
            values.append(tokens[index])
            index += 1
        today_values = [
            repr(math.radians(float(v))) if k in angles else v for k, v in enumerate(values)
        ]
        shown = " ".join(f"{float(v):.6g}" for v in today_values)
        notes.append(f'"{" ".join([token, *values])}" is now "{flag} {shown}" (radians); {LATER}')
        out += [flag, *today_values]
    return out


def _is_number(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


def _split_equals(tokens: list[str]) -> list[str]:
    """``--flag=value`` as ``--flag value`` for the flags this module rewrites."""
    old = {*GROUPS_OLD, *SYNTH, *ESTIMATE, "--to", "--tracker"}
    old |= {f"--{key.replace('_', '-')}" for key in GEOMETRY}
    out: list[str] = []
    for token in tokens:
        flag, equals, value = token.partition("=")
        out += [flag, value] if equals and flag in old else [token]
    return out


def _command(command: str, rest: list[str]) -> str:
    """Today's subcommand (with export's target) for the old ``command`` and its options."""
    if command == "odometry" and any(flag in rest for flag in ESTIMATOR_FLAGS):
        return "estimate"
    if command == "calibrate" and "--track-from-gyro" in rest:
        return "calibrate-gyro"
    if command == "calibrate" and ("--gps-topic" in rest or "--pose-topic" in rest):
        return "calibrate-driving"
    if command == "follow" and _value(rest, "--tracker") == "mppi":
        return "mppi"
    if command == "export" and _value(rest, "--to") is not None:
        return f"export {_value(rest, '--to')}"
    return command


def _why_moved(command: str, rest: list[str]) -> str:
    return {
        "odometry": "with measurements or a smoother",
        "calibrate": "without ground truth",
        "follow": "--tracker mppi",
        "export": f"--to {_value(rest, '--to')}",
    }[command]


def _value(rest: list[str], flag: str) -> str | None:
    """The value after ``flag`` in ``rest``, or None."""
    if flag in rest and rest.index(flag) + 1 < len(rest):
        return rest[rest.index(flag) + 1]
    return None


def _rewrite(
    command: str, rest: list[str], known: Mapping[str, object], notes: list[str], moved: bool
) -> tuple[list[str], list[str]]:
    """The tokens kept and today's options added in place of the old ones; ``moved``: the
    old subcommand became ``command``, so the option that chose it goes."""
    # animate's --frames N is no pair: an old --frame there was argparse's abbreviation of it.
    pairs = {
        old
        for flag, (olds, _) in GROUPS.items()
        if known.get(flag) in (len(olds), "+")
        for old in olds
    }
    kept: list[str] = []
    added: list[str] = []
    grouped: dict[str, str] = {}
    moved_flags = {"--to"} if moved and command.startswith("export ") else set()
    moved_flags |= {"--track-from-gyro"} if moved and command.startswith("calibrate-") else set()
    tokens = iter(rest)
    for token in tokens:
        if token in moved_flags or (moved and command == "mppi" and token == "--tracker"):
            if token != "--track-from-gyro":
                next(tokens, None)
            continue
        if token in known or not token.startswith("--"):
            kept.append(token)
            continue
        if token in pairs:
            grouped[token] = next(tokens, "")
            continue
        value = None if token in SWITCHES else next(tokens, "")
        new = _single(command, token, value, known)
        if new is None:
            kept += [token] + ([] if value is None else [value])
            continue
        old = token if value is None else f"{token} {value}"
        now = f'"{" ".join(new)}"' if new else f"left out: {_left_out(command, token)}"
        notes.append(f'"{old}" is now {now}; {LATER}')
        added += new
    for flag, (olds, defaults) in GROUPS.items():
        given = [old for old in olds if old in grouped]
        if not given:
            continue
        if defaults is None and len(given) < len(olds):
            raise MisspelledError(
                f"{', '.join(given)} without {', '.join(o for o in olds if o not in grouped)}: "
                f"today {flag} takes them together ({', '.join(olds)}, in that order)"
            )
        values = [grouped.get(old, d) for old, d in zip(olds, defaults or olds, strict=True)]
        was = " ".join(f"{old} {grouped[old]}" for old in given)
        notes.append(f'"{was}" is now "{flag} {" ".join(values)}"; {LATER}')
        added += [flag, *values]
    return kept, added


def _single(
    command: str, token: str, value: str | None, known: Mapping[str, object]
) -> list[str] | None:
    """Today's tokens for one old option (``[]``: left out), or None when it is not old."""
    key = token[2:].replace("-", "_")
    if key in GEOMETRY and "--robot" in known:
        return ["--robot", f"{key}={value}"]
    if command == "synth" and token in SYNTH:
        flag, name = SYNTH[token]
        return [flag, f"{name}={value}"]
    if command == "estimate" and token in ESTIMATE:
        if token == "--slip-test":
            value = "true" if value == "episodes" else "false"
        return ["--settings", f"{ESTIMATE[token]}={value}"]
    if command == "estimate" and token in ALWAYS:
        return []
    if command in ("plan", "follow", "mppi") and token == "--method":
        return []
    return None


def _left_out(command: str, token: str) -> str:
    if token in ALWAYS:
        return "estimate writes the twist and the covariance always"
    return f"{command} never integrated by it"
