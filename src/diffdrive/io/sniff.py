"""What kind of file a path is, before any reader opens it."""

from __future__ import annotations

from pathlib import Path

__all__ = ["is_bag"]


def is_bag(path: str | Path) -> bool:
    """Whether ``path`` is a ROS 1 bag, an MCAP file or a ROS 2 bag folder."""
    path = Path(path)
    return path.suffix in (".bag", ".mcap") or (path / "metadata.yaml").is_file()
