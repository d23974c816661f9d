"""A test's child process, bounded by the processor time it uses rather than the wall clock:
a busy machine slows a child down but cannot make it fail, and one that loops forever is still
stopped (``RLIMIT_CPU``: the kernel ends it past its processor seconds).

The limit is set by a small launcher that then becomes the command (``os.execv``), not by a
``preexec_fn``: that would make ``subprocess`` fork the test's process, whose at-fork hooks
(JAX's, once a test has imported it) warn, and warnings are errors here."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Sequence

# Processor seconds a child may use: ten times what the slowest takes on a quiet machine (the
# twin's run of the odometry tests, about a minute), far past any one that works.
CPU_SECONDS = 600

_LAUNCH = (
    "import os, resource, shutil, sys; "
    "limit = int(sys.argv[1]); resource.setrlimit(resource.RLIMIT_CPU, (limit, limit)); "
    "os.execv(shutil.which(sys.argv[2]) or sys.argv[2], sys.argv[2:])"
)


def run_bounded(command: Sequence[str], **options) -> subprocess.CompletedProcess:
    """``subprocess.run`` of ``command`` with its output captured as text, its processor time
    bounded by ``CPU_SECONDS`` (its wall time is not: load only slows it)."""
    launcher = [sys.executable, "-c", _LAUNCH, str(CPU_SECONDS), *command]
    return subprocess.run(launcher, capture_output=True, text=True, **options)
