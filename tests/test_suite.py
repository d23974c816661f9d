"""The suite's own shape: collecting it starts no other process (the twin's run of the
odometry tests once started from ``conftest.py`` at collection), and its child processes are
bounded by processor time, which a busy machine does not use up, not by the wall clock."""

import sys
from pathlib import Path

import pytest

from processes import CPU_SECONDS, run_bounded

TESTS = Path(__file__).resolve().parent

# Collect the suite in a fresh interpreter in which starting a process fails loudly.
COLLECT = """
import subprocess, sys
import pytest

def refused(*args, **options):
    raise AssertionError(f"a process was started while collecting: {args[:1]}")

subprocess.Popen.__init__ = refused
sys.exit(pytest.main(["--collect-only", "-q", "-p", "no:xdist", "-p", "no:cacheprovider"]))
"""


@pytest.mark.slow
def test_collecting_the_suite_starts_no_process():
    done = run_bounded([sys.executable, "-c", COLLECT], cwd=TESTS.parent)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    assert "tests collected" in done.stdout


def test_a_child_that_loops_is_stopped_by_its_processor_time(monkeypatch):
    """A child spinning forever is ended by the kernel past its processor seconds (here 1 s),
    not left to hang the suite."""
    monkeypatch.setattr("processes.CPU_SECONDS", 1)
    done = run_bounded([sys.executable, "-c", "while True: pass"])
    assert done.returncode != 0
    assert CPU_SECONDS >= 60  # the suite's own bound: far past any child that works


@pytest.mark.parametrize(
    ("environment", "command", "leaves_out_slow"),
    [({}, "test", True), ({"CI": "1"}, "test", False), ({}, "test-all", False)],
    ids=["make test", "make test in CI", "make test-all"],
)
def test_the_slow_tests_run_in_ci_and_in_test_all(environment, command, leaves_out_slow):
    """``make test`` stays within minutes by leaving out the tests marked slow, but not where
    ``CI`` is set (``.ci/run`` sets it), nor in ``make test-all``: no assertion is dropped."""
    import os
    import shutil
    import subprocess

    if shutil.which("make") is None:
        pytest.skip("make is not on this machine")
    settings = {k: v for k, v in os.environ.items() if k not in ("CI", "SLOW", "MAKEFLAGS")}
    done = subprocess.run(
        ["make", "-n", command],
        cwd=TESTS.parent,
        env=settings | environment,
        capture_output=True,
        text=True,
        check=True,
    )
    pytest_lines = [line for line in done.stdout.splitlines() if "-m pytest" in line]
    assert len(pytest_lines) == 1, done.stdout
    assert ('-m "not slow"' in pytest_lines[0]) == leaves_out_slow
    assert 'export CI="${CI:-1}"' in (TESTS.parent / ".ci" / "run").read_text()
