"""Robot files: the geometry of a robot (and its encoders' resolution) as TOML, and the noise a
calibration found for it.

The noise is an optional table ``[noise]`` of ``EstimatorSettings``' noise parts by their names,
each with all its fields (``[noise.wheel_noise]`` ``left``, ``right`` in m;
``[noise.gyro_noise]`` the ``GyroNoise`` fields): what ``calibrate-driving`` identified, which
``odometry``, ``estimate`` and ``export`` then use where no flag gives the same figure."""

from __future__ import annotations

import dataclasses
import math
import sys
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from diffdrive.atomic import atomic_write
from diffdrive.io.tables import TableError
from diffdrive.model import DiffDrive, Robot
from diffdrive.sensor_noise import GyroNoise, WheelNoise
from diffdrive.skid_steer import SkidSteer

__all__ = [
    "NOISE_PARTS",
    "ROBOT_KEYS",
    "overridden",
    "read_robot",
    "read_robot_noise",
    "robot_from_settings",
    "write_robot",
]

ROBOT_KEYS = (
    "wheel_radius",
    "left_wheel_radius",
    "right_wheel_radius",
    "track_width",
    "half_track",
    "axle_offset",
    "icr_left",
    "icr_right",
    "icr_x",
    "ticks_per_revolution",
)
"""What a robot file may set: the ``DiffDrive``'s (or ``SkidSteer``'s) arguments, and the encoders'
resolution."""

NOISE_PARTS: dict[str, type] = {"wheel_noise": WheelNoise, "gyro_noise": GyroNoise}
"""What a robot file's ``[noise]`` table may hold: ``EstimatorSettings``' parts by name."""
NoisePart = WheelNoise | GyroNoise


def read_robot(path: str | Path) -> dict[str, float]:
    """The settings of a robot file (TOML): ``ROBOT_KEYS``, lengths in m.

    Returns them as a dict; ``TableError`` names the file (and the line, for a syntax error)
    of anything wrong.
    """
    path = Path(path)
    settings = load_toml(path, "a robot file")
    settings.pop("noise", None)  # read_robot_noise's
    unknown = sorted(set(settings) - set(ROBOT_KEYS))
    if unknown:
        raise TableError(
            f"{path}: unknown setting {unknown[0]!r}; a robot file may set {', '.join(ROBOT_KEYS)}"
        )
    return {key: toml_number(path, key, value) for key, value in settings.items()}


def read_robot_noise(path: str | Path) -> dict[str, NoisePart]:
    """The noise a robot file's ``[noise]`` table holds (see the module), by part name
    (``"wheel_noise"``: a ``WheelNoise``, ``"gyro_noise"``: a ``GyroNoise``); none, an empty
    dict. ``TableError`` names the file and the part of anything wrong."""
    path = Path(path)
    table = load_toml(path, "a robot file").get("noise", {})
    if not isinstance(table, dict):
        raise TableError(f"{path}: noise must be a table ([noise.wheel_noise], ...)")
    found: dict[str, NoisePart] = {}
    for name, fields in table.items():
        kind = NOISE_PARTS.get(name)
        if kind is None:
            raise TableError(
                f"{path}: unknown noise part {name!r}; a robot file's noise may hold "
                f"{', '.join(NOISE_PARTS)}"
            )
        wanted = [item.name for item in dataclasses.fields(kind)]
        if not isinstance(fields, dict) or set(fields) != set(wanted):
            raise TableError(f"{path}: noise.{name} must give each of {', '.join(wanted)}")
        numbers = {key: toml_number(path, f"noise.{name}.{key}", fields[key]) for key in wanted}
        try:
            found[name] = kind(**numbers)
        except ValueError as exc:
            raise TableError(f"{path}: noise.{name}: {exc}") from None
    return found


def toml_value(text: str) -> object:
    """``text`` as TOML reads a value (a number, true, a "string", an array), else the text."""
    tomllib = _tomllib()
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text


def _tomllib():
    if sys.version_info >= (3, 11):
        import tomllib
    else:
        import tomli as tomllib
    return tomllib


def load_toml(path: Path, what: str) -> dict[str, Any]:
    """The TOML document at ``path`` (``what`` names the kind of file in messages);
    ``TableError`` names the file and what is wrong with it."""
    tomllib = _tomllib()
    try:
        with path.open("rb") as handle:
            return tomllib.load(handle)
    except OSError as exc:
        raise TableError(f"{path}: cannot read: {exc.strerror}") from None
    except tomllib.TOMLDecodeError as exc:
        raise TableError(f"{path}: not valid TOML: {exc}") from None
    except UnicodeDecodeError as exc:
        raise TableError(
            f"{path}: not UTF-8 text (byte {exc.object[exc.start]:#04x} at offset {exc.start}); "
            f"{what} is TOML, which is UTF-8"
        ) from None


def toml_number(path: Path, key: str, value: object) -> float:
    """A TOML value that must be a finite number, as a float; ``TableError`` names the file
    and key otherwise."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise TableError(f"{path}: {key} must be a number, got {value!r}")
    try:
        number = float(value)
    except OverflowError:  # an integer of hundreds of digits
        number = math.inf
    if not math.isfinite(number):
        shown = f"{value!r}" if len(repr(value)) < 40 else f"a number of {len(repr(value))} digits"
        raise TableError(f"{path}: {key} must be finite, got {shown}")
    return number


def write_robot(
    path: str | Path,
    settings: dict[str, float],
    comment: str = "",
    noise: Mapping[str, NoisePart] | None = None,
) -> None:
    """Write a robot file (TOML) that ``read_robot`` reads back: ``ROBOT_KEYS`` only, and
    ``noise`` (parts by ``NOISE_PARTS`` name) that ``read_robot_noise`` reads back."""
    unknown = sorted(set(settings) - set(ROBOT_KEYS))
    if unknown:
        raise ValueError(f"not a robot setting: {unknown[0]!r}")
    parts = dict(noise or {})
    for name, part in parts.items():
        if not isinstance(part, NOISE_PARTS.get(name, ())):
            raise ValueError(f"not a robot file's noise part: {name!r} = {part!r}")
    with atomic_write(path) as stream:
        stream.writelines(f"# {line}\n" for line in comment.splitlines())
        stream.writelines(f"{key} = {float(value)!r}\n" for key, value in settings.items())
        for name, part in parts.items():
            stream.write(f"\n[noise.{name}]\n")
            fields = dataclasses.asdict(part).items()
            stream.writelines(f"{key} = {value!r}\n" for key, value in fields)


# Settings that say the same thing in two ways: an override of one replaces the other too.
_SAME_LENGTH = ("track_width", "half_track")
_RADII = ("left_wheel_radius", "right_wheel_radius")


def overridden(
    settings: dict[str, Any],
    overrides: dict[str, Any],
    named: Callable[[str], str] = str,
) -> dict[str, Any]:
    """A robot file's ``settings`` with ``overrides`` applied, consistently: an override of
    the track (``track_width`` or ``half_track``) replaces the file's either; ``wheel_radius``
    replaces the file's radii; one of the left and right radii keeps the file's
    ``wheel_radius`` for the other wheel. Two overrides of the same length are refused, the
    keys called by ``named`` (the command line's flags, say)."""
    given = set(overrides)
    for group in (_SAME_LENGTH, ("wheel_radius", *_RADII)):
        clash = [key for key in group if key in given]
        if len(clash) > 1 and not set(clash) <= set(_RADII):
            raise ValueError(
                f"{' and '.join(map(named, clash))} both given: they set the same length, give one"
            )
    merged = dict(settings)
    if given & set(_SAME_LENGTH):
        for key in _SAME_LENGTH:
            merged.pop(key, None)
    if "wheel_radius" in given:
        for key in _RADII:
            merged.pop(key, None)
    if given & set(_RADII) and "wheel_radius" in merged:
        radius = merged.pop("wheel_radius")
        for key in _RADII:
            merged.setdefault(key, radius)
    merged.update(overrides)
    return merged


def robot_from_settings(settings: dict[str, Any], where: str = "") -> Robot:
    """The robot model a robot file's settings describe (``ROBOT_KEYS`` less the ticks): a
    ``SkidSteer`` by its ICRs, else a ``DiffDrive``. ``ValueError`` names ``where`` (e.g.
    ``" (in robot.toml)"``) and what is wrong."""
    try:
        if any(key.startswith("icr_") for key in settings):
            if {"track_width", "half_track", "axle_offset"} & settings.keys():
                raise ValueError(
                    "a skid-steer robot has icr_left, icr_right and icr_x instead of "
                    "track_width, half_track and axle_offset"
                )
            return SkidSteer(**settings)
        return DiffDrive(**settings)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"robot{where}: {exc}") from None
