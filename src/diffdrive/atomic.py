"""Atomic writes: every file diffdrive writes appears whole or not at all.

A writer writes a temporary file beside the target and renames it over the target once it is
complete, so a failure (an error, a full disk, an interrupt) leaves the target as it was.
"""

from __future__ import annotations

import contextlib
import os
import signal
import tempfile
import threading
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
    # it is recorded until the name is held, and then handled inside the try. (Masking the
    # signals would not do: another thread, such as a BLAS pool's, takes them instead.)
    held = _hold_interrupts()
    try:
        try:
            handle, temporary = tempfile.mkstemp(
                dir=path.parent or ".", prefix=f".{path.stem}.", suffix=path.suffix
            )
        except OSError as exc:  # named by the target, not the hidden file it never made
            raise TableError(f"cannot write {path}: {exc.strerror} (in {folder})") from None
        os.close(handle)
        _release(held)
        held = None
        yield Path(temporary)
        # mkstemp makes the file private (0600); give it the mode a plain open would.
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(temporary, 0o666 & ~umask)
        try:
            os.replace(temporary, path)
        except OSError as exc:
            raise TableError(f"cannot write {path}: {exc.strerror}") from None
    except BaseException:
        if temporary is not None:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(temporary)
        raise
    finally:
        _release(held)


_INTERRUPTS = (signal.SIGINT, signal.SIGTERM)


def _hold_interrupts():
    """Have SIGINT and SIGTERM recorded instead of handled, until ``_release``; what that
    needs to put back (None outside the main thread, where Python runs no handler, and where
    a handler was set outside Python)."""
    if threading.current_thread() is not threading.main_thread():
        return None
    if any(signal.getsignal(number) is None for number in _INTERRUPTS):
        return None  # a handler set outside Python cannot be put back from here
    caught: list[int] = []
    previous = {
        number: signal.signal(number, lambda n, _: caught.append(n)) for number in _INTERRUPTS
    }
    return previous, caught


def _release(held) -> None:
    """Put the handlers back, then hand each interrupt recorded meanwhile to its own handler
    (an exception it raises comes out here); None: nothing to do."""
    if held is None:
        return
    previous, caught = held
    for number, handler in previous.items():
        signal.signal(number, handler)
    pending = list(caught)
    caught.clear()  # handed on once, even if a handler's exception brings us back here
    for number in pending:
        handler = previous[number]
        if callable(handler):
            handler(number, None)
        elif handler == signal.SIG_DFL:
            signal.raise_signal(number)


@contextlib.contextmanager
def atomic_write(path: str | Path) -> Iterator[TextIO]:
    """A text file to write that appears at ``path`` only once it is complete."""
    with atomic_output(path) as temporary, temporary.open("w", newline="") as stream:
        yield stream
