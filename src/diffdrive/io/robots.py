"""Robot files: the geometry of a robot (and its encoders' resolution) as TOML."""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Any

from diffdrive.atomic import atomic_write
from diffdrive.io.tables import TableError
from diffdrive.model import DiffDrive, Robot
from diffdrive.skid_steer import SkidSteer

__all__ = ["ROBOT_KEYS", "read_robot", "robot_from_settings", "write_robot"]

# What a robot file may set: the DiffDrive's arguments, and the encoders' resolution.
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


def read_robot(path: str | Path) -> dict[str, float]:
    """The settings of a robot file (TOML): ``ROBOT_KEYS``, lengths in m.

    Returns them as a dict; ``TableError`` names the file (and the line, for a syntax error)
    of anything wrong.
    """
    if sys.version_info >= (3, 11):
        import tomllib
    else:
        import tomli as tomllib
    path = Path(path)
    try:
        with path.open("rb") as handle:
            settings = tomllib.load(handle)
    except OSError as exc:
        raise TableError(f"{path}: cannot read: {exc.strerror}") from None
    except tomllib.TOMLDecodeError as exc:
        raise TableError(f"{path}: not valid TOML: {exc}") from None
    except UnicodeDecodeError as exc:
        raise TableError(
            f"{path}: not UTF-8 text (byte {exc.object[exc.start]:#04x} at offset {exc.start}); "
            "a robot file is TOML, which is UTF-8"
        ) from None
    unknown = sorted(set(settings) - set(ROBOT_KEYS))
    if unknown:
        raise TableError(
            f"{path}: unknown setting {unknown[0]!r}; a robot file may set {', '.join(ROBOT_KEYS)}"
        )
    for key, value in settings.items():
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise TableError(f"{path}: {key} must be a number, got {value!r}")
        if not math.isfinite(float(value)):
            raise TableError(f"{path}: {key} must be finite, got {value!r}")
    return {key: float(value) for key, value in settings.items()}


def write_robot(path: str | Path, settings: dict[str, float], comment: str = "") -> None:
    """Write a robot file (TOML) that ``read_robot`` reads back: ``ROBOT_KEYS`` only."""
    unknown = sorted(set(settings) - set(ROBOT_KEYS))
    if unknown:
        raise ValueError(f"not a robot setting: {unknown[0]!r}")
    with atomic_write(path) as stream:
        stream.writelines(f"# {line}\n" for line in comment.splitlines())
        stream.writelines(f"{key} = {float(value)!r}\n" for key, value in settings.items())


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
