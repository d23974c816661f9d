"""The C core's builds for the tests (``c/``): on this machine with its C compiler and make,
and for a Cortex-M4F with Debian's ``gcc-arm-none-eabi`` and ``libnewlib-arm-none-eabi``, run
under ``qemu-system-arm`` (``.ci/run`` installs the three). Without the cross tools the tests
that need them are skipped with a message naming the packages, except under CI, where they
fail. Each build goes to a folder of its own, so parallel workers never share one."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from processes import run_bounded

ROOT = Path(__file__).resolve().parents[1]
C = ROOT / "c"
PACKAGES = "gcc-arm-none-eabi libnewlib-arm-none-eabi qemu-system-arm"
# QEMU's model of the MPS2 board with the AN386 image: a Cortex-M4 with its FPU.
QEMU = ["qemu-system-arm", "-M", "mps2-an386", "-nographic"]


def require_cross(what: str) -> None:
    """Skip (fail under CI) unless the cross compiler, newlib and QEMU are here."""
    missing = [tool for tool in ("arm-none-eabi-gcc", "qemu-system-arm") if not shutil.which(tool)]
    if not missing:
        specs = subprocess.run(
            ["arm-none-eabi-gcc", "-print-file-name=rdimon.specs"],
            capture_output=True,
            text=True,
            check=False,
        ).stdout.strip()
        if not Path(specs).is_file():
            missing.append("newlib's rdimon.specs")
    if not missing:
        return
    message = (
        f"{', '.join(missing)} not found, so {what} did NOT run. "
        f"Install them with: apt-get install {PACKAGES}"
    )
    if os.environ.get("CI"):
        pytest.fail(message + "; .ci/run installs them, so under CI this is a failure")
    pytest.skip(message)


def build(target: str, where: Path) -> Path:
    """``make -C c target`` into ``where`` (its host/ and cortex-m4/ folders); ``where``."""
    done = run_bounded(
        ["make", "-C", str(C), target, f"HOST={where / 'host'}", f"ARM={where / 'cortex-m4'}"]
    )
    assert done.returncode == 0, f"make {target} failed:\n{done.stdout}\n{done.stderr}"
    return where


def qemu(elf: Path, *arguments: str, icount: bool = False) -> subprocess.CompletedProcess:
    """Run ``elf`` on the Cortex-M4F under QEMU, its command line (the program's name, then
    ``arguments``, file names relative to the ELF's folder) given through semihosting."""
    words = ",".join(f"arg={word}" for word in (elf.name, *arguments))
    command = [*QEMU, *(["-icount", "shift=0"] if icount else [])]
    command += ["-semihosting-config", f"enable=on,target=native,{words}", "-kernel", elf.name]
    return run_bounded(command, cwd=elf.parent)


def status_codes() -> dict[str, int]:
    """The C API's status codes by name, read from its header."""
    header = (C / "include" / "diffdrive" / "real.h").read_text()
    return {name: int(value) for name, value in re.findall(r"\b(DD_[A-Z_]+) = (\d+)", header)}
