"""Headless Chromium for the browser tests (the learning page, the documentation site):
Debian's ``chromium`` (``apt-get install chromium``; ``.ci/run`` installs it), driven by
Playwright, which never downloads a browser of its own. Without it the tests are skipped with
a message that says so, except under CI, where they fail."""

import os
import shutil
import socket
import subprocess
import time
import urllib.request
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

SCREENSHOTS = Path(__file__).resolve().parents[1] / "build"
# Chromium as root in a closed network: no sandbox, no GPU, and no calls home.
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]


def chromium(what: str) -> str:
    """Chromium's path; skipped (failed under CI) without it, naming ``what`` did not run."""
    path = (
        os.environ.get("CHROMIUM") or shutil.which("chromium") or shutil.which("chromium-browser")
    )
    if path:
        return path
    message = (
        f"Chromium not found, so the browser tests of {what} did NOT run. "
        "Install it with: apt-get install chromium (or set CHROMIUM to its path)"
    )
    if os.environ.get("CI"):
        pytest.fail(message + "; .ci/run installs it, so under CI this is a failure")
    pytest.skip(message)


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def note_outside(url: str, outside: list[str]) -> None:
    """Add ``url`` to ``outside`` where it leaves this machine."""
    if not url.startswith(("http://127.0.0.1", "ws://127.0.0.1", "data:", "blob:")):
        outside.append(url)


@contextmanager
def serving(command: list[str], port: int, why: Callable[[], str], **options) -> Iterator[str]:
    """``command`` run as a server on ``port`` until the block ends: yields its address once
    it answers (60 s at most; else the test fails with ``why()``)."""
    server = subprocess.Popen(command, **options)
    address = f"http://127.0.0.1:{port}/"
    try:
        deadline = time.monotonic() + 60
        while True:
            try:
                with urllib.request.urlopen(address, timeout=2):
                    break
            except OSError:
                if server.poll() is not None or time.monotonic() > deadline:
                    pytest.fail(f"{' '.join(command[:4])} did not serve: {why()}")
                time.sleep(0.3)
        yield address
    finally:
        server.terminate()
        server.wait(timeout=30)
