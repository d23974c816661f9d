"""Atomic writes: every file diffdrive writes appears whole or not at all.

A writer writes a temporary file beside the target and renames it over the target once it is
complete, so a failure (an error, a full disk, an interrupt) leaves the target as it was.
"""

from __future__ import annotations

import contextlib
import os
import signal
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
    temporary: str | None = None
    # An interrupt (Ctrl-C, or SIGTERM, which the command line turns into one) inside mkstemp,
    # after it made the file and before its name is known here, would leave the file behind:
    # they wait until the name is held, and then arrive inside the try.
    held = _hold_interrupts()
    try:
        handle, temporary = tempfile.mkstemp(
            dir=path.parent or ".", prefix=f".{path.stem}.", suffix=path.suffix
        )
        os.close(handle)
        _release(held)
        held = None
        yield Path(temporary)
        # mkstemp makes the file private (0600); give it the mode a plain open would.
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(temporary, 0o666 & ~umask)
        os.replace(temporary, path)
    except BaseException:
        if temporary is not None:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(temporary)
        raise
    finally:
        _release(held)


_INTERRUPTS = {signal.SIGINT, signal.SIGTERM}


def _hold_interrupts() -> set | None:
    """Hold SIGINT and SIGTERM back from this thread; the mask it replaced (None where
    signals cannot be held, as on Windows)."""
    if not hasattr(signal, "pthread_sigmask"):
        return None
    return signal.pthread_sigmask(signal.SIG_BLOCK, _INTERRUPTS)


def _release(held: set | None) -> None:
    """Put back the mask ``held`` (a held interrupt arrives now); None: nothing to do."""
    if held is not None:
        signal.pthread_sigmask(signal.SIG_SETMASK, held)


@contextlib.contextmanager
def atomic_write(path: str | Path) -> Iterator[TextIO]:
    """A text file to write that appears at ``path`` only once it is complete."""
    with atomic_output(path) as temporary, temporary.open("w", newline="") as stream:
        yield stream
