"""A test's child process, bounded by the processor time it uses rather than the wall clock:
a busy machine slows a child down but cannot make it fail, and one that loops forever is still
stopped (``RLIMIT_CPU``: the kernel ends it past its processor seconds)."""

from __future__ import annotations

import resource
import subprocess
from collections.abc import Sequence

# Processor seconds a child may use: ten times what the slowest takes on a quiet machine (the
# twin's run of the odometry tests, about a minute), far past any one that works.
CPU_SECONDS = 600


def _limit_cpu() -> None:
    resource.setrlimit(resource.RLIMIT_CPU, (CPU_SECONDS, CPU_SECONDS))


def run_bounded(command: Sequence[str], **options) -> subprocess.CompletedProcess:
    """``subprocess.run`` of ``command`` with its output captured as text, its processor time
    bounded by ``CPU_SECONDS`` (its wall time is not: load only slows it)."""
    return subprocess.run(
        list(command), capture_output=True, text=True, preexec_fn=_limit_cpu, **options
    )
