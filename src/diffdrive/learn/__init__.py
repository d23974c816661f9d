"""A page for learning differential-drive kinematics: ``diffdrive learn``.

The page is a marimo app (``page.py``; extra ``diffdrive[learn]``) served from this machine:
no internet is needed and nothing comes from a CDN. Its numbers are the library's
(``lessons``), its pictures are matplotlib figures (``drawings``).
"""

from __future__ import annotations

import importlib.util
import os
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

__all__ = ["PAGE", "export_page", "missing_extra", "serve", "serve_command"]

PAGE = Path(__file__).with_name("page.py")
"""The marimo notebook of the learning page."""


def missing_extra() -> str | None:
    """Why the page cannot run here (the extra is not installed), or None when it can."""
    missing = [name for name in ("marimo", "matplotlib") if importlib.util.find_spec(name) is None]
    if not missing:
        return None
    return (
        f"the learning page needs {' and '.join(missing)}: install the extra with "
        "pip install 'diffdrive[learn]'"
    )


@contextmanager
def _page_copy() -> Iterator[Path]:
    """The page copied into a scratch folder, removed afterwards: marimo keeps a session cache
    beside the notebook it runs, and the installed package is no place for one."""
    with tempfile.TemporaryDirectory(prefix="diffdrive-learn-") as folder:
        yield Path(shutil.copy(PAGE, folder))


def serve_command(page: Path, port: int | None = None, browser: bool = True) -> list[str]:
    """The command line that serves ``page`` on 127.0.0.1 (marimo picks a free port if none)."""
    command = [
        sys.executable,
        "-m",
        "marimo",
        "run",
        str(page),
        "--host",
        "127.0.0.1",
        "--no-token",
        "--no-sandbox",
        "--no-check",
    ]
    if port is not None:
        command += ["--port", str(port)]
    if not browser:
        command.append("--headless")
    return command


def _check_extra() -> None:
    reason = missing_extra()
    if reason is not None:
        raise RuntimeError(reason)


def serve(port: int | None = None, browser: bool = True) -> int:
    """Serve the page until interrupted, opening it in the browser unless ``browser=False``;
    returns marimo's exit code."""
    _check_extra()
    with _page_copy() as page:
        try:
            return subprocess.call(serve_command(page, port, browser))
        except KeyboardInterrupt:
            return 0


def export_page(path: Path) -> None:
    """Write the page, run once with its default values, as one static HTML file.

    The file is a snapshot for a course website: its controls do not recompute, and when
    opened it loads marimo's page scripts from the jsDelivr CDN (marimo's static export does
    not inline them), so it needs the internet, unlike ``serve``.
    """
    _check_extra()
    path = Path(path)
    if not path.parent.is_dir():
        raise FileNotFoundError(f"no such folder for the page: {path.parent}")
    # marimo writes the file itself: let it write beside the target, then replace, so that a
    # failed export leaves an existing page as it was.
    with (
        _page_copy() as page,
        tempfile.TemporaryDirectory(dir=path.parent, prefix=".diffdrive-") as folder,
    ):
        scratch = Path(folder) / path.name
        done = subprocess.run(
            [sys.executable, "-m", "marimo", "export", "html", str(page), "-o", str(scratch)],
            capture_output=True,
            text=True,
        )
        if done.returncode != 0 or not scratch.is_file():
            raise RuntimeError(f"marimo could not export the page: {done.stderr.strip()}")
        os.replace(scratch, path)
