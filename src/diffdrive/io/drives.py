"""Drive files: what ``diffdrive identify`` found of how a drive answers (TOML), for
``diffdrive export wpilib`` and for a reader.

Sections (each optional, at least one):

- ``[feedforward]``: ``ks`` (V), ``kv`` (V s/m), ``ka`` (V s^2/m) and ``delay`` (s) of the
  wheels' mean surface speed (the linear channel of WPILib's drivetrain form, as SysId gives
  them);
- ``[angular]``: the same of half the wheels' speed difference (the angular channel);
- ``[response]``: a velocity-commanded drive's ``delay`` (s), ``time_constant`` (s), ``gain``
  and ``acceleration`` (rad/s^2 of the wheels; absent: no limit found).
"""

from __future__ import annotations

from pathlib import Path

from diffdrive.atomic import atomic_write
from diffdrive.io.robots import load_toml, toml_number
from diffdrive.io.tables import TableError

__all__ = ["DRIVE_SECTIONS", "read_drive", "write_drive"]

DRIVE_SECTIONS = {
    "feedforward": ("ks", "kv", "ka", "delay"),
    "angular": ("ks", "kv", "ka", "delay"),
    "response": ("delay", "time_constant", "gain", "acceleration"),
}


def read_drive(path: str | Path) -> dict[str, dict[str, float]]:
    """The sections of a drive file; ``TableError`` names the file and what is wrong."""
    path = Path(path)
    document = load_toml(path, "a drive file")
    unknown = sorted(set(document) - set(DRIVE_SECTIONS))
    if unknown or not document:
        raise TableError(
            f"{path}: a drive file holds sections {', '.join(DRIVE_SECTIONS)}; got "
            f"{', '.join(unknown) or 'none'}"
        )
    sections = {}
    for name, values in document.items():
        if not isinstance(values, dict):
            raise TableError(f"{path}: {name} must be a section ([{name}])")
        extra = sorted(set(values) - set(DRIVE_SECTIONS[name]))
        if extra:
            keys = ", ".join(DRIVE_SECTIONS[name])
            raise TableError(f"{path}: [{name}] has no key {extra[0]!r}; it holds {keys}")
        sections[name] = {key: toml_number(path, f"{name}.{key}", v) for key, v in values.items()}
    return sections


def write_drive(path: str | Path, sections: dict[str, dict[str, float]], comment: str) -> None:
    """A drive file that ``read_drive`` reads back, whole or not at all."""
    for name, values in sections.items():
        if name not in DRIVE_SECTIONS or set(values) - set(DRIVE_SECTIONS[name]):
            raise ValueError(f"not a drive file's section or key: [{name}] {sorted(values)}")
    with atomic_write(path) as stream:
        stream.writelines(f"# {line}\n" for line in comment.splitlines())
        for name, values in sections.items():
            stream.write(f"\n[{name}]\n")
            stream.writelines(f"{key} = {float(value)!r}\n" for key, value in values.items())
