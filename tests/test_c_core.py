"""The freestanding C core (``c/``): the host build against the Python library on a table of
drives, the Cortex-M4F build under QEMU on the same table and over an hour at 100 Hz, its size
and its cost in instructions, its refusals through the C API, and its kinematics and limiter
against the Python ones.

The Python extension binds the same sources, so the host build must give the library's
numbers to the bit; the float build differs by single precision only."""

from __future__ import annotations

import ctypes
import json
import math
import re
import shutil
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from hypothesis import example, given
from hypothesis import strategies as st

import diffdrive as dd
from firmware import C, build, qemu, require_cross, status_codes
from processes import run_bounded


@dataclass(frozen=True)
class Drive:
    """A robot (m, counts, bits, m) and its encoder readings ``(t, left, right)``."""

    name: str
    r_left: float
    r_right: float
    track: float
    ticks_per_revolution: int
    counter_bits: int  # 0: counters that do not roll over
    k: tuple[float, float]
    readings: np.ndarray  # (n, 3): s, counts, counts

    def file_text(self) -> str:
        robot = (
            f"robot {self.r_left!r} {self.r_right!r} {self.track!r} "
            f"{self.ticks_per_revolution} {self.counter_bits} {self.k[0]!r} {self.k[1]!r}\n"
        )
        return robot + "".join(f"{float(t)!r} {int(a)} {int(b)}\n" for t, a, b in self.readings)


def _readings(left_rate, right_rate, seconds: float, rate: float, counts: int, bits: int):
    """Counter readings of wheels turning at left_rate(t), right_rate(t) rad/s."""
    t = np.arange(int(seconds * rate) + 1) / rate
    angles = [np.concatenate([[0.0], np.cumsum(f(t[:-1]) / rate)]) for f in (left_rate, right_rate)]
    ticks = [np.floor(angle / (2 * np.pi) * counts).astype(np.int64) for angle in angles]
    if bits:  # the counter's bits as it reads them, unsigned
        ticks = [tick % (1 << bits) for tick in ticks]
    return np.stack([t, *ticks], axis=-1)


DRIVES = [
    Drive(
        "TurtleBot-like, 16-bit counters rolling over",
        0.033,
        0.033,
        0.16,
        4096,
        16,
        (1e-4, 1e-4),
        _readings(lambda t: 8 + 4 * np.sin(t), lambda t: 8 - 4 * np.sin(0.7 * t), 30, 50, 4096, 16),
    ),
    Drive(
        "unequal wheels, reversing through zero, 32-bit counters",
        0.049,
        0.051,
        0.31,
        2048,
        32,
        (2e-4, 3e-4),
        _readings(lambda t: 6 * np.cos(0.5 * t), lambda t: 5 * np.cos(0.4 * t), 20, 100, 2048, 32),
    ),
    Drive(
        "spinning on the spot, counters that never roll over",
        0.1,
        0.1,
        0.5,
        1000,
        0,
        (5e-5, 5e-5),
        _readings(lambda t: -3 + 0 * t, lambda t: 3 + 0 * t, 15, 20, 1000, 0),
    ),
    Drive(
        "12-bit counters rolling over every few readings",
        0.06,
        0.06,
        0.4,
        1024,
        12,
        (1e-4, 1e-4),
        _readings(lambda t: 20 + 0 * t, lambda t: 18 + np.sin(t), 10, 40, 1024, 12),
    ),
]


def python_odometry(drive: Drive) -> np.ndarray:
    """The library's ``t x y theta P_xx P_xy P_xt P_yy P_yt P_tt`` after each reading."""
    robot = dd.DiffDrive(
        left_wheel_radius=drive.r_left, right_wheel_radius=drive.r_right, track_width=drive.track
    )
    odometry = dd.Odometry(
        robot,
        "exact",
        ticks_per_revolution=drive.ticks_per_revolution,
        counter_bits=drive.counter_bits or None,
        wheel_noise=drive.k,
    )
    rows = []
    for k, (t, left, right) in enumerate(drive.readings):
        odometry.update_ticks(int(left), int(right), float(t))
        if k:
            pose, cov = odometry.pose, odometry.covariance
            rows.append([t, pose.x, pose.y, pose.theta, *cov[np.triu_indices(3)]])
    return np.array(rows)


def stream(command: list[str], folder: Path, drive: Drive) -> np.ndarray:
    (folder / "drive.txt").write_text(drive.file_text())
    done = run_bounded(command, cwd=folder)
    assert done.returncode == 0, done.stderr
    assert done.stderr == "", done.stderr  # no reading of the table is refused
    return np.loadtxt(done.stdout.splitlines(), ndmin=2)


@pytest.fixture(scope="module")
def host(tmp_path_factory) -> Path:
    return build("host", tmp_path_factory.mktemp("c")) / "host"


@pytest.fixture(scope="module")
def cortex(tmp_path_factory) -> Path:
    require_cross("the Cortex-M4F build's tests")
    return build("cortex-m4", tmp_path_factory.mktemp("c")) / "cortex-m4"


@pytest.mark.slow
@pytest.mark.parametrize("drive", DRIVES, ids=lambda d: d.name)
def test_the_host_build_gives_the_librarys_odometry_to_the_bit(host, drive):
    got = stream([str(host / "odometry_stream"), "drive.txt"], host, drive)
    want = python_odometry(drive)
    assert got.shape == want.shape
    np.testing.assert_array_equal(got[:, :4], want[:, :4])  # the same source: exactly
    np.testing.assert_allclose(got[:, 4:], want[:, 4:], rtol=1e-15, atol=0)


@pytest.mark.slow
@pytest.mark.parametrize("drive", DRIVES, ids=lambda d: d.name)
def test_the_cortex_m4_build_under_qemu_follows_the_library(cortex, drive):
    (cortex / "drive.txt").write_text(drive.file_text())
    done = qemu(cortex / "odometry_stream.elf", "drive.txt")
    assert done.returncode == 0, done.stderr
    assert done.stderr == "", done.stderr
    got, want = np.loadtxt(done.stdout.splitlines(), ndmin=2), python_odometry(drive)
    assert got.shape == want.shape
    # single precision: the geometry rounded to floats (1e-7), then rounding along the path
    np.testing.assert_allclose(got[:, 1:4], want[:, 1:4], rtol=0, atol=2e-5)
    # the covariance to 1e-4 of its largest variance (a small correlation cancels in floats)
    scale = want[:, [4, 7, 9]].max(axis=1, keepdims=True)
    assert np.all(np.abs(got[:, 4:] - want[:, 4:]) <= 1e-4 * scale)


def _hour(path: Path) -> None:
    """An hour of a 100 Hz wandering drive, geometry that floats hold exactly (so the builds
    differ by their arithmetic, not by their inputs)."""
    r, track = float(np.float32(0.033)), float(np.float32(0.16))
    readings = _readings(
        lambda t: 8 + 4 * np.sin(2 * np.pi * t / 60) + 2 * np.sin(2 * np.pi * t / 7.3),
        lambda t: 8 - 4 * np.sin(2 * np.pi * t / 60) + 2 * np.sin(2 * np.pi * t / 5.1),
        3600,
        100,
        4096,
        16,
    )
    lines = [f"robot {r!r} {r!r} {track!r} 4096 16 1e-4 1e-4\n"]
    lines += [f"{t:.2f} {int(a)} {int(b)}\n" for t, a, b in readings]
    path.write_text("".join(lines))


@pytest.mark.slow
def test_an_hour_at_100_hz_in_single_precision_stays_within_a_millimetre(host, cortex):
    _hour(cortex / "hour.txt")
    double = run_bounded([str(host / "odometry_stream"), str(cortex / "hour.txt")])
    single = qemu(cortex / "odometry_stream.elf", "hour.txt")
    assert double.returncode == 0, double.stderr
    assert single.returncode == 0, single.stderr
    a = np.loadtxt(double.stdout.splitlines(), usecols=(1, 2, 3))
    b = np.loadtxt(single.stdout.splitlines(), usecols=(1, 2, 3))
    assert len(a) == len(b) == 360_000
    assert np.hypot(*(a[:, :2] - b[:, :2]).T).max() <= 1e-3
    assert np.abs(a[:, 2] - b[:, 2]).max() <= 1e-5


@pytest.mark.slow
def test_the_library_fits_a_microcontroller(cortex):
    objects = sorted(cortex.glob("*.o"))
    done = run_bounded(["arm-none-eabi-size", *map(str, objects)])
    text = {
        Path(line.split()[-1]).stem: int(line.split()[0]) for line in done.stdout.splitlines()[1:]
    }
    assert set(text) == {"kinematics", "odometry", "limiter", "filter", "history"}
    assert sum(text.values()) <= 16 * 1024
    assert text["odometry"] <= 4 * 1024
    needed = run_bounded(["arm-none-eabi-nm", "-u", *map(str, objects)]).stdout
    defined = run_bounded(["arm-none-eabi-nm", "--defined-only", *map(str, objects)]).stdout
    own = set(re.findall(r" [TDRB] (\S+)", defined))  # one object of the library's calling another
    symbols = set(re.findall(r"\bU (\S+)", needed)) - own
    libm = {"sinf", "cosf", "sqrtf", "logf", "remainderf", "fmaf", "fmaxf", "fminf"}
    helpers = {s for s in symbols if s.startswith("__aeabi_")}  # the compiler's run-time
    assert symbols - helpers - libm <= {"memcpy", "memset", "memmove"}, symbols


@pytest.mark.slow
def test_an_update_and_a_filter_step_cost_what_a_microcontroller_can_spend(cortex):
    done = qemu(cortex / "step_cost.elf", icount=True)
    assert done.returncode == 0, done.stdout + done.stderr
    cost = {name: int(value) for name, value in re.findall(r"(\w+) (\d+)", done.stdout)}
    assert 100 < cost["odometry_update"] <= 1000
    assert 100 < cost["odometry_update_offset"] <= 1000
    assert 500 < cost["filter_step"] <= 5000


@pytest.mark.slow
def test_the_stream_names_a_refused_reading_and_goes_on(host, tmp_path):
    (tmp_path / "bad.txt").write_text(
        "robot 0.033 0.033 0.16 4096 16 1e-4 1e-4 50\n"
        "0 0 0\n0.01 5 5\nnot a reading\n0.005 10 10\n0.02 60000 10\nnan 7 7\n0.04 20 20\n"
    )
    done = run_bounded([str(host / "odometry_stream"), "bad.txt"], cwd=tmp_path)
    assert done.returncode == 0
    refused = done.stderr.splitlines()
    assert [line.split(":")[0].split(" (")[0] for line in refused] == [
        f"refused line {n}" for n in (4, 5, 6, 7)
    ]
    assert "time went backwards" in refused[1]
    assert "max_wheel_speed" in refused[2]
    assert "not finite" in refused[3]
    assert [row.split()[0] for row in done.stdout.splitlines()] == ["0.01", "0.040000000000000001"]


# -- the C API through ctypes ----------------------------------------------------------------


class CDrive(ctypes.Structure):
    _fields_ = [(name, ctypes.c_double) for name in ("r_left", "r_right", "track", "offset")]


class OdometryConfig(ctypes.Structure):
    _fields_ = [
        ("drive", CDrive),
        ("method", ctypes.c_int),
        ("ticks_per_revolution", ctypes.c_double),
        ("counter_bits", ctypes.c_int),
        ("max_wheel_speed", ctypes.c_double),
        ("k_left", ctypes.c_double),
        ("k_right", ctypes.c_double),
    ]


class Limits(ctypes.Structure):
    _fields_ = [
        (name, ctypes.c_double)
        for name in (
            "max_velocity",
            "max_reverse_velocity",
            "max_acceleration",
            "max_deceleration",
            "max_reverse_acceleration",
            "max_reverse_deceleration",
            "max_jerk",
        )
    ]


STATE = 2048  # bytes: more than any of the library's state structs


@pytest.fixture(scope="module")
def library(host):
    lib = ctypes.CDLL(str(host / "libdiffdrive.so"))
    double_p = ctypes.POINTER(ctypes.c_double)
    lib.dd_odometry_init.argtypes = [ctypes.c_void_p, ctypes.POINTER(OdometryConfig)]
    lib.dd_odometry_ticks.argtypes = [ctypes.c_void_p, double_p, ctypes.c_int64, ctypes.c_int64]
    lib.dd_odometry_increments.argtypes = [
        ctypes.c_void_p,
        double_p,
        ctypes.c_double,
        ctypes.c_double,
    ]
    lib.dd_forward.argtypes = [
        ctypes.POINTER(CDrive),
        ctypes.c_double,
        ctypes.c_double,
        *[double_p] * 3,
    ]
    lib.dd_inverse.argtypes = [
        ctypes.POINTER(CDrive),
        ctypes.c_double,
        ctypes.c_double,
        *[double_p] * 2,
    ]
    lib.dd_turning_radius.argtypes = [ctypes.POINTER(CDrive), ctypes.c_double, ctypes.c_double]
    lib.dd_turning_radius.restype = ctypes.c_double
    lib.dd_limiter_init.argtypes = [
        ctypes.c_void_p,
        ctypes.c_int,
        ctypes.POINTER(Limits),
        ctypes.c_double,
    ]
    lib.dd_limiter_step.argtypes = [ctypes.c_void_p, double_p, ctypes.c_double, double_p]
    lib.dd_status_text.restype = ctypes.c_char_p
    return lib


def _odometry(library, max_wheel_speed=50.0):
    state = ctypes.create_string_buffer(STATE)
    config = OdometryConfig(
        CDrive(0.033, 0.033, 0.16, 0.0), 2, 4096.0, 16, max_wheel_speed, 1e-4, 1e-4
    )
    assert library.dd_odometry_init(state, ctypes.byref(config)) == 0
    t = ctypes.c_double(0.0)
    assert library.dd_odometry_ticks(state, ctypes.byref(t), 100, 100) == 0
    t.value = 0.01
    assert library.dd_odometry_ticks(state, ctypes.byref(t), 120, 125) == 0
    return state


@pytest.mark.slow
@pytest.mark.parametrize(
    ("reading", "status"),
    [
        ((0.02, math.nan, 0.0), "DD_NOT_FINITE"),  # increments
        ((math.inf, 0.001, 0.001), "DD_NOT_FINITE"),
        ((0.005, 0.001, 0.001), "DD_TIME_BACKWARDS"),
        ((0.01, 0.001, 0.0), "DD_TIME_STILL"),
        ((0.02, 5.0, 0.0), "DD_TOO_FAST"),  # 500 rad/s past a limit of 50
    ],
)
def test_the_c_api_refuses_a_reading_with_its_code_and_keeps_its_state(library, reading, status):
    state = _odometry(library)
    before = state.raw
    t, left, right = reading
    got = library.dd_odometry_increments(state, ctypes.byref(ctypes.c_double(t)), left, right)
    assert got == status_codes()[status]
    assert state.raw == before
    assert library.dd_status_text(got)  # and a sentence to log


@pytest.mark.slow
def test_the_c_api_refuses_counter_jumps_wrong_widths_and_null_pointers(library):
    codes, state = status_codes(), _odometry(library)
    before = state.raw
    t = ctypes.c_double(0.02)
    # 16 bits: a reading past 2^16 - 1 cannot come from the counter
    assert (
        library.dd_odometry_ticks(state, ctypes.byref(t), 70000, 125) == codes["DD_COUNTER_RANGE"]
    )
    # 32,000 counts in 0.01 s: a jump past the robot's speed (or a roll-over misread)
    assert library.dd_odometry_ticks(state, ctypes.byref(t), 32120, 125) == codes["DD_TOO_FAST"]
    assert library.dd_odometry_ticks(None, ctypes.byref(t), 1, 1) == codes["DD_NULL"]
    assert state.raw == before
    config = OdometryConfig(CDrive(0.0, 0.033, 0.16, 0.0), 2, 4096.0, 16, 50.0, 1e-4, 1e-4)
    assert library.dd_odometry_init(state, ctypes.byref(config)) == codes["DD_BAD_SETTING"]


KINEMATICS = [  # (r_left, r_right, track, offset), (left, right) rad/s
    ((0.05, 0.05, 0.3, 0.0), (1.0, 2.0)),
    ((0.049, 0.051, 0.31, 0.07), (-3.0, 4.5)),
    ((0.1, 0.1, 0.5, -0.2), (2.0, 2.0)),
    ((0.033, 0.035, 0.16, 0.0), (-5.0, 5.0)),
]


@pytest.mark.slow
@pytest.mark.parametrize(("geometry", "wheels"), KINEMATICS)
def test_the_c_kinematics_are_the_models(library, geometry, wheels):
    r_left, r_right, track, offset = geometry
    robot = dd.DiffDrive(
        left_wheel_radius=r_left, right_wheel_radius=r_right, track_width=track, axle_offset=offset
    )
    drive = CDrive(*geometry)
    out = [ctypes.c_double() for _ in range(3)]
    library.dd_forward(ctypes.byref(drive), *wheels, *map(ctypes.byref, out))
    twist = robot.to_twist(wheels)
    np.testing.assert_allclose(
        [v.value for v in out], [twist.vx, twist.vy, twist.omega], rtol=1e-15, atol=1e-15
    )
    back = [ctypes.c_double() for _ in range(2)]
    library.dd_inverse(ctypes.byref(drive), twist.vx, twist.omega, *map(ctypes.byref, back))
    np.testing.assert_allclose([v.value for v in back], wheels, rtol=1e-12)
    want = robot.turning_radius(wheels)
    got = library.dd_turning_radius(ctypes.byref(drive), *wheels)
    assert got == pytest.approx(want, rel=1e-12) or (math.isinf(got) and math.isinf(want))


LIMITS = {  # two channels each: without jerk limits, with them on both, on one
    "acceleration": (
        dd.Limits(max_velocity=1.0, max_reverse_velocity=0.5, max_acceleration=2.0,
                  max_deceleration=3.0),
        dd.Limits(max_velocity=2.0, max_acceleration=4.0, max_reverse_acceleration=1.0),
    ),
    "jerk": (
        dd.Limits(max_velocity=1.0, max_reverse_velocity=0.5, max_acceleration=2.0,
                  max_deceleration=3.0, max_jerk=10.0),
        dd.Limits(max_velocity=2.0, max_acceleration=4.0, max_reverse_acceleration=1.0,
                  max_jerk=25.0),
    ),
    "jerk on one channel": (
        dd.Limits(max_velocity=1.5, max_acceleration=2.0, max_jerk=8.0),
        dd.Limits(max_velocity=2.0, max_acceleration=3.0),
    ),
}  # fmt: skip


def _c_limits(limits: dd.Limits) -> Limits:
    return Limits(*limits.bounds())  # v, v reverse, acc, dec, acc reverse, dec reverse, jerk


@pytest.mark.slow
@given(
    st.lists(
        st.tuples(
            st.one_of(st.none(), st.tuples(st.floats(-3, 3), st.floats(-3, 3))),
            st.floats(0.005, 0.2),
        ),
        min_size=1,
        max_size=40,
    )
)
@example(steps=[((0.0, 6.222806744061141e-140), 0.125), ((1.0, 1.0), 0.125)])  # a gap too small
def test_the_c_limiter_follows_the_python_one_step_by_step(library, steps):
    for channels in LIMITS.values():
        python = dd.Limiter(channels, timeout=0.3)
        state = ctypes.create_string_buffer(STATE)
        limits = (Limits * 2)(*map(_c_limits, channels))
        assert library.dd_limiter_init(state, 2, limits, 0.3) == 0
        out = (ctypes.c_double * 2)()
        for target, dt in steps:
            want = python.step(target, dt)
            given_target = None if target is None else (ctypes.c_double * 2)(*target)
            assert library.dd_limiter_step(state, given_target, dt, out) == 0
            np.testing.assert_allclose(list(out), want, rtol=1e-12, atol=1e-12)


# -- the header diffdrive export writes, read by the compiler that builds the firmware --------

READ_BACK = r"""
#include <stdio.h>
#include "diffdrive_robot.h"

int main(void) {
    dd_odometry odometry;
    dd_filter filter;
    if (dd_odometry_init(&odometry, &diffdrive_odometry) != DD_OK) return 1;
    if (dd_filter_init(&filter, &diffdrive_filter) != DD_OK) return 2;
    const dd_odometry_config *c = &diffdrive_odometry;
    printf("%.17g %.17g %.17g %.17g %.17g %d %.17g %.17g\n", (double)c->drive.r_left,
           (double)c->drive.r_right, (double)c->drive.track, (double)c->drive.offset,
           (double)c->ticks_per_revolution, c->counter_bits, (double)c->k_left,
           (double)c->k_right);
    long long left = 65000, right = 65100; /* 16-bit counters about to roll over */
    for (int k = 0; k <= 100; ++k) {
        double t = 0.02 * k;
        if (dd_odometry_ticks(&odometry, &t, (left + 40 * k) % 65536, (right + 47 * k) % 65536)
            != DD_OK)
            return 3;
    }
    dd_real pose[3];
    dd_odometry_pose(&odometry, pose);
    printf("%.17g %.17g %.17g\n", (double)pose[0], (double)pose[1], (double)pose[2]);
    return 0;
}
"""


def export_header(folder: Path, robot: str) -> None:
    """``diffdrive export --to c-header`` of ``robot`` (its options) into folder."""
    command = [sys.executable, "-m", "diffdrive", "export", "--to", "c-header", "-q"]
    exported = run_bounded([*command, "-o", "diffdrive_robot.h", *robot.split()], cwd=folder)
    assert exported.returncode == 0, exported.stderr


@pytest.mark.slow
def test_the_exported_header_builds_the_firmwares_odometry(host, tmp_path):
    export_header(
        tmp_path,
        "--left-wheel-radius 0.0331 --right-wheel-radius 0.0329 --track-width 0.161 "
        "--ticks-per-revolution 4096 --counter-bits 16 --k 2e-4",
    )
    (tmp_path / "read.c").write_text(READ_BACK)
    include = ["-I", str(tmp_path), "-I", str(C / "include")]
    compiled = run_bounded(
        [
            "cc",
            "-std=c99",
            "-Wall",
            "-Werror",
            *include,
            "read.c",
            str(host / "libdiffdrive.a"),
            "-lm",
            "-o",
            "read",
        ],
        cwd=tmp_path,
    )
    assert compiled.returncode == 0, compiled.stderr
    done = run_bounded(["./read"], cwd=tmp_path)
    assert done.returncode == 0, done.stdout
    settings, pose = (np.array(line.split(), dtype=float) for line in done.stdout.splitlines())
    np.testing.assert_array_equal(settings, [0.0331, 0.0329, 0.161, 0.0, 4096, 16, 2e-4, 2e-4])
    robot = dd.DiffDrive(left_wheel_radius=0.0331, right_wheel_radius=0.0329, track_width=0.161)
    odometry = dd.Odometry(robot, "exact", ticks_per_revolution=4096, counter_bits=16)
    for k in range(101):
        odometry.update_ticks((65000 + 40 * k) % 65536, (65100 + 47 * k) % 65536, 0.02 * k)
    np.testing.assert_array_equal(pose, odometry.pose.to_array())


@pytest.mark.slow
def test_the_exported_header_builds_for_a_cortex_m4(cortex, tmp_path):
    export_header(
        tmp_path,
        "--wheel-radius 0.033 --track-width 0.16 --ticks-per-revolution 1440 --counter-bits 32 "
        "--k 1e-4",
    )
    (tmp_path / "read.c").write_text(READ_BACK.replace("printf", "(void)printf"))
    flags = ["-mcpu=cortex-m4", "-mthumb", "-mfpu=fpv4-sp-d16", "-mfloat-abi=hard", "-DDD_SINGLE"]
    compiled = run_bounded(
        [
            "arm-none-eabi-gcc",
            *flags,
            "-std=c99",
            "-Wall",
            "-Werror",
            "-c",
            "-I",
            str(tmp_path),
            "-I",
            str(C / "include"),
            "read.c",
            "-o",
            "read.o",
        ],
        cwd=tmp_path,
    )
    assert compiled.returncode == 0, compiled.stderr


# -- the layouts firmware builds take ----------------------------------------------------------


@pytest.mark.slow
def test_the_arduino_layout_finds_its_headers_in_src_alone(tmp_path):
    """The Arduino IDE compiles a library's src/ with src/ as its only include folder."""
    layout = tmp_path / "arduino" / "diffdrive"
    made = run_bounded(["make", "-C", str(C), "arduino", f"ARDUINO={layout}"])
    assert made.returncode == 0, made.stderr
    assert (layout / "library.properties").read_text().startswith("name=diffdrive\n")
    sources = sorted(str(path) for path in (layout / "src").glob("*.c"))
    assert len(sources) == 5
    compiled = run_bounded(
        ["cc", "-std=c99", "-Wall", "-Werror", "-c", "-I", str(layout / "src"), *sources],
        cwd=tmp_path,
    )
    assert compiled.returncode == 0, compiled.stderr


@pytest.mark.slow
def test_cmake_and_platformio_take_the_folder_as_it_is(tmp_path):
    """PlatformIO reads c/library.json (src/ and include/, its own defaults); CMake builds
    c/CMakeLists.txt, here in single precision."""
    manifest = json.loads((C / "library.json").read_text())
    assert (manifest["build"]["srcDir"], manifest["build"]["includeDir"]) == ("src", "include")
    assert all((C / "include" / header).is_file() for header in manifest["headers"])
    if shutil.which("cmake") is None:
        pytest.skip("cmake not found, so the CMake build did NOT run (apt-get install cmake)")
    configured = run_bounded(
        ["cmake", "-S", str(C), "-B", "b", "-DDIFFDRIVE_SINGLE=ON"], cwd=tmp_path
    )
    assert configured.returncode == 0, configured.stderr
    built = run_bounded(["cmake", "--build", "b"], cwd=tmp_path)
    assert built.returncode == 0, built.stdout + built.stderr
    assert (tmp_path / "b" / "libdiffdrive.a").is_file()
