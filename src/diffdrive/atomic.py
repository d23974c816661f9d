"""Atomic writes: every file diffdrive writes appears whole or not at all.

A writer writes a temporary file beside the target and renames it over the target once it is
complete, so a failure (an error, a full disk, an interrupt) leaves the target as it was.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import TextIO

from diffdrive.errors import TableError

__all__ = ["atomic_output", "atomic_write"]


@contextlib.contextmanager
def atomic_output(path: str | Path) -> Iterator[Path]:
    """A temporary path beside ``path`` (same suffix), renamed to ``path`` once written.

    On any failure the temporary file goes and ``path`` is left as it was.
    """
    path = Path(path)
    folder = path.parent
    if not folder.is_dir():
        raise TableError(f"cannot write {path}: the folder {folder} does not exist")
    handle, temporary = tempfile.mkstemp(
        dir=path.parent or ".", prefix=f".{path.stem}.", suffix=path.suffix
    )
    os.close(handle)
    try:
        yield Path(temporary)
        # mkstemp makes the file private (0600); give it the mode a plain open would.
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(temporary, 0o666 & ~umask)
        os.replace(temporary, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(temporary)
        raise


@contextlib.contextmanager
def atomic_write(path: str | Path) -> Iterator[TextIO]:
    """A text file to write that appears at ``path`` only once it is complete."""
    with atomic_output(path) as temporary, temporary.open("w", newline="") as stream:
        yield stream
