"""The C core in the firmware and in Python, side by side in one run (issue 53's figures).

1. The host build (double) against ``diffdrive.Odometry`` on an hour of a 100 Hz drive with
   16-bit counters: the largest pose and covariance differences (the extension binds the same
   source, so they should be 0).
2. The Cortex-M4F build (single precision, ``-Os``) under QEMU against the host build on the
   same hour, and on an hour of circling (3,000 rad of heading): the largest position and
   heading differences at any reading.
3. The library's code size at ``-Os`` for the Cortex-M4F, and the symbols it needs.
4. Instructions per odometry update with its covariance and per filter step with a gyro,
   counted under QEMU (``-icount shift=0``: one instruction a nanosecond of the virtual clock,
   read off the board's SysTick, c/cortex-m4/step_cost.c).
5. The Python extension before and after the core moved into ``c/``: one
   ``Odometry.update_ticks`` and a smoothed ``estimate_trajectory`` of 20,000 readings (the
   wheels' noise given, so that both revisions run the same model), each
   revision's extension built in a clone of its own and timed in alternating rounds (medians,
   wall and processor time).

Needs make, a C compiler, and for 2 to 4 Debian's gcc-arm-none-eabi, libnewlib-arm-none-eabi
and qemu-system-arm.

    python benchmarks/bench_c_core.py [--against 3ecb469] [--rounds 5] [--seconds 3600]
        [--updates 100000] [--log 20000]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import re
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

import diffdrive as dd

ROOT = Path(__file__).resolve().parents[1]
QEMU = ["qemu-system-arm", "-M", "mps2-an386", "-nographic"]


def make(target: str, where: Path) -> None:
    subprocess.run(
        [
            "make",
            "-s",
            "-C",
            str(ROOT / "c"),
            target,
            f"HOST={where / 'host'}",
            f"ARM={where / 'cortex-m4'}",
        ],
        check=True,
        capture_output=True,
    )


def qemu(elf: Path, *arguments: str, icount: bool = False) -> str:
    words = ",".join(f"arg={word}" for word in (elf.name, *arguments))
    command = [*QEMU, *(["-icount", "shift=0"] if icount else [])]
    command += ["-semihosting-config", f"enable=on,target=native,{words}", "-kernel", elf.name]
    return subprocess.run(
        command, cwd=elf.parent, check=True, capture_output=True, text=True
    ).stdout


def drive_file(path: Path, left_rate, right_rate, seconds: int) -> np.ndarray:
    """An hour at 100 Hz of 16-bit counter readings; geometry floats hold exactly."""
    rate, counts = 100, 4096
    t = np.arange(seconds * rate + 1) / rate
    angles = [np.concatenate([[0.0], np.cumsum(f(t[:-1]) / rate)]) for f in (left_rate, right_rate)]
    ticks = [np.floor(a / (2 * np.pi) * counts).astype(np.int64) % 65536 for a in angles]
    r, track = float(np.float32(0.033)), float(np.float32(0.16))
    lines = [f"robot {r!r} {r!r} {track!r} {counts} 16 1e-4 1e-4\n"]
    lines += [f"{a:.2f} {b} {c}\n" for a, b, c in zip(t, *ticks, strict=True)]
    path.write_text("".join(lines))
    return np.stack([t, *ticks], axis=-1)


def wander(t):
    return 8 + 4 * np.sin(2 * np.pi * t / 60) + 2 * np.sin(2 * np.pi * t / 7.3)


def wander_right(t):
    return 8 - 4 * np.sin(2 * np.pi * t / 60) + 2 * np.sin(2 * np.pi * t / 5.1)


def circle_left(t):
    return 6 + 0.5 * np.sin(2 * np.pi * t / 13)


def circle_right(t):
    return 10 + 0.5 * np.sin(2 * np.pi * t / 17)


def host_against_python(host: Path, folder: Path, seconds: int) -> None:
    readings = drive_file(folder / "wander.txt", wander, wander_right, seconds)
    out = subprocess.run(
        [str(host / "odometry_stream"), "wander.txt"],
        cwd=folder,
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    got = np.loadtxt(out.splitlines())
    r, track = float(np.float32(0.033)), float(np.float32(0.16))
    odometry = dd.Odometry(
        dd.DiffDrive(r, track),
        "exact",
        ticks_per_revolution=4096,
        counter_bits=16,
        wheel_noise=(1e-4, 1e-4),
    )
    want = np.empty_like(got)
    for k, (t, left, right) in enumerate(readings):
        odometry.update_ticks(int(left), int(right), float(t))
        if k:
            cov = odometry.covariance
            want[k - 1] = [t, *odometry.pose.to_array(), *cov[np.triu_indices(3)]]
    pose = np.abs(got[:, 1:4] - want[:, 1:4]).max()
    cov = (np.abs(got[:, 4:] - want[:, 4:]) / np.abs(want[:, 4:]).clip(1e-300)).max()
    print("1. host build (double) against diffdrive.Odometry, an hour at 100 Hz")
    print(
        f"   {len(got)} readings: largest pose difference {pose:.3g}, covariance {cov:.3g} relative"
    )


def float_against_double(host: Path, cortex: Path, seconds: int) -> None:
    print("2. Cortex-M4F build (float, -Os) under QEMU against the host build (double)")
    for name, left, right in (
        ("wander", wander, wander_right),
        ("circle", circle_left, circle_right),
    ):
        drive_file(cortex / f"{name}.txt", left, right, seconds)
        double = subprocess.run(
            [str(host / "odometry_stream"), f"{name}.txt"],
            cwd=cortex,
            check=True,
            capture_output=True,
            text=True,
        ).stdout
        a = np.loadtxt(double.splitlines(), usecols=(1, 2, 3))
        b = np.loadtxt(
            qemu(cortex / "odometry_stream.elf", f"{name}.txt").splitlines(), usecols=(1, 2, 3)
        )
        position = np.hypot(*(a[:, :2] - b[:, :2]).T).max()
        heading = np.abs(a[:, 2] - b[:, 2]).max()
        print(
            f"   {name:6s} {len(a)} readings, |heading| up to {np.abs(a[:, 2]).max():.0f} rad: "
            "largest position "
            f"difference {1e3 * position:.3g} mm, heading {heading:.2g} rad"
        )


def sizes(cortex: Path) -> None:
    objects = sorted(cortex.glob("*.o"))
    listing = subprocess.run(
        ["arm-none-eabi-size", *map(str, objects)], check=True, capture_output=True, text=True
    ).stdout.splitlines()[1:]
    text = {Path(line.split()[-1]).stem: int(line.split()[0]) for line in listing}
    needed = subprocess.run(
        ["arm-none-eabi-nm", "-u", *map(str, objects)], check=True, capture_output=True, text=True
    ).stdout
    defined = subprocess.run(
        ["arm-none-eabi-nm", "--defined-only", *map(str, objects)],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    own = set(re.findall(r" [TDRB] (\S+)", defined))
    symbols = sorted(set(re.findall(r"\bU (\S+)", needed)) - own)
    code = {}  # .text alone, without the constants (.rodata)
    for path in objects:
        sections = subprocess.run(
            ["arm-none-eabi-size", "-A", str(path)], check=True, capture_output=True, text=True
        ).stdout
        code[path.stem] = sum(
            int(size) for size in re.findall(r"^\.text\S*\s+(\d+)", sections, re.M)
        )
    print("3. code size at -Os, Cortex-M4F (bytes: .text, and with the constants)")
    for name, size in text.items():
        print(f"   {name:12s} {code[name]:6d} {size:6d}")
    total, whole = sum(code.values()), sum(text.values())
    print(f"   {'all':12s} {total:6d} {whole:6d} ({total / 1024:.1f} and {whole / 1024:.1f} KiB)")
    print(f"   needs: {', '.join(symbols)}")


def instructions(cortex: Path) -> None:
    out = qemu(cortex / "step_cost.elf", icount=True)
    cost = dict(re.findall(r"(\w+) (\d+)", out))
    print("4. instructions a call on the Cortex-M4F (QEMU -icount, SysTick)")
    print(f"   odometry update with covariance        {cost['odometry_update']:>6s}")
    print(f"   the same, reference point off the axle {cost['odometry_update_offset']:>6s}")
    print(f"   filter step with a gyro (bias, scale)  {cost['filter_step']:>6s}")


TIMED = r"""
import json, sys, time, resource
import numpy as np
import diffdrive as dd
from diffdrive.estimation import Gyro, estimate_trajectory
robot = dd.DiffDrive(0.033, 0.16)
n, m = int(sys.argv[1]), int(sys.argv[2])
rng = np.random.default_rng(0)
ticks = np.cumsum(rng.integers(40, 60, (n, 2)), axis=0) % 65536
left, right, times = ticks[:, 0].tolist(), ticks[:, 1].tolist(), (np.arange(n) * 0.01).tolist()
def clocks():
    return time.perf_counter(), resource.getrusage(resource.RUSAGE_SELF).ru_utime
w0, c0 = clocks()
noise = (1e-4, 1e-4)
odometry = dd.Odometry(
    robot, "exact", ticks_per_revolution=4096, counter_bits=16, wheel_noise=noise
)
update = odometry.update_ticks
for a, b, t in zip(left, right, times):
    update(a, b, t)
w1, c1 = clocks()
increments = rng.uniform(0.05, 0.1, (m - 1, 2))
stamps = np.arange(m) * 0.01
rates = np.concatenate([[0.0], (increments[:, 1] - increments[:, 0]) * 0.033 / 0.16 / 0.01])
try:  # the wheels' noise given, as both revisions spell it: the same model in both
    from diffdrive.estimation import EstimatorSettings
    given = {"settings": EstimatorSettings(wheel_noise=noise)}
except ImportError:
    given = {"wheel_noise": noise}
estimate_trajectory(robot, stamps, increments, gyro=Gyro(stamps, rates), smooth=True, **given)
w2, c2 = clocks()
print(json.dumps({"update": [(w1 - w0) / n, (c1 - c0) / n], "smoother": [w2 - w1, c2 - c1]}))
"""


def extension_speed(against: str, rounds: int, sizes: tuple[int, int], folder: Path) -> None:
    clones = {}
    for name, revision in (("before", against), ("after", "HEAD")):
        clone = folder / name
        subprocess.run(["git", "clone", "-q", str(ROOT), str(clone)], check=True)
        subprocess.run(["git", "-C", str(clone), "checkout", "-q", revision], check=True)
        subprocess.run(
            [sys.executable, "setup.py", "-q", "build_ext", "--inplace"],
            cwd=clone,
            check=True,
            capture_output=True,
        )
        clones[name] = clone
    taken = {name: [] for name in clones}
    for _ in range(rounds):
        for name, clone in clones.items():
            env = {**os.environ, "PYTHONPATH": str(clone / "src")}
            out = subprocess.run(
                [sys.executable, "-c", TIMED, *map(str, sizes)],
                env=env,
                check=True,
                capture_output=True,
                text=True,
            ).stdout
            taken[name].append(json.loads(out))
    print(f"5. the extension before (--against) and after, medians of {rounds} alternating rounds")
    for what, unit, scale in (
        ("update", "ns an Odometry.update_ticks", 1e9),
        ("smoother", f"ms a smoothed {sizes[1]:,}-reading estimate_trajectory", 1e3),
    ):
        wall = {n: statistics.median(r[what][0] for r in taken[n]) * scale for n in taken}
        cpu = {n: statistics.median(r[what][1] for r in taken[n]) * scale for n in taken}
        print(
            f"   {unit}: before {wall['before']:.1f} wall / {cpu['before']:.1f} CPU, after "
            f"{wall['after']:.1f} / {cpu['after']:.1f}: {_ratio(wall)} wall, {_ratio(cpu)} CPU"
        )


def _ratio(times: dict[str, float]) -> str:
    """after / before, or why there is none: a small run's CPU time can fall below the
    clock's tick and read 0."""
    if times["before"] <= 0.0:
        return "no ratio (the time before read 0, below the clock's tick) for"
    return f"{times['after'] / times['before']:.2f} x"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--against", default="3ecb469", help="the revision before the move")
    parser.add_argument("--rounds", type=int, default=9)
    parser.add_argument("--seconds", type=int, default=3600, help="the drives' length, s")
    parser.add_argument("--updates", type=int, default=100_000, help="Odometry updates timed")
    parser.add_argument("--log", type=int, default=20_000, help="the smoothed log's readings")
    args = parser.parse_args()
    print(
        f"machine: {platform.machine()}, {os.cpu_count()} cores; python {platform.python_version()}"
    )
    with tempfile.TemporaryDirectory() as scratch:
        where = Path(scratch)
        make("host", where)
        make("cortex-m4", where)
        host, cortex = where / "host", where / "cortex-m4"
        host_against_python(host, where, args.seconds)
        float_against_double(host, cortex, args.seconds)
        sizes(cortex)
        instructions(cortex)
        extension_speed(args.against, args.rounds, (args.updates, args.log), where)


if __name__ == "__main__":
    main()
