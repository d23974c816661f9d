"""Simulation throughput, side by side in one process: diffdrive vs a C loop and loops in Python.

Cases (issue 3): one robot over 10^7 steps, and 10^3 robots times 10^4 steps, with the exact
update. Contenders:

- diffdrive's ``simulate`` with the numba kernel and with the NumPy prefix sums;
- a C loop of the same update, compiled at -O3 from the source below when a C compiler is
  present and called through ctypes on the same arrays (it allocates its output, as we do);
- a plain Python loop, roboticstoolbox-python's ``DiffSteer`` (its ``deriv``, an Euler step,
  as its own ``run`` does) and robotpy-wpimath's ``Pose2d.exp`` (exact), when installed. These
  three are timed on the first 2e5 / 2e4 steps and reported per step.

Every contender is called once before it is timed (the kernel compiles or loads its cache
then). Prints the machine, the median of several runs, the ratios, and the peak memory
(tracemalloc) of diffdrive's call relative to its output pose array. Then the start-up: the
first kernel call of fresh processes, with the kernel's cache on disk and with an empty one,
next to importing numba alone.

    pip install -e '.[bench]'        # numba and the peers
    python benchmarks/bench_simulate.py [--repeats 5] [--quick]
"""

from __future__ import annotations

import argparse
import ctypes
import math
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import tracemalloc
import warnings
from functools import partial
from pathlib import Path

import numpy as np

import diffdrive as dd
from diffdrive.demo import example_robot
from timing import median_time  # benchmarks/timing.py

C_SOURCE = r"""
#include <math.h>
/* The exact update, one robot after another: pose (x, y, theta) per step from held
   wheel velocities. poses has (steps + 1) * 3 doubles per robot. */
void simulate_exact(const double *wheels, long robots, long steps, double dt, double r_l,
                    double r_r, double track, double *poses) {
    for (long n = 0; n < robots; ++n) {
        const double *w = wheels + 2 * n * steps;
        double *p = poses + 3 * n * (steps + 1);
        double x = 0.0, y = 0.0, th = 0.0;
        p[0] = x; p[1] = y; p[2] = th;
        for (long k = 0; k < steps; ++k) {
            double left = r_l * w[2 * k], right = r_r * w[2 * k + 1];
            double v = 0.5 * (left + right), om = (right - left) / track;
            double half = 0.5 * om * dt;
            double sinc = fabs(half) < 1e-4 ? 1.0 - half * half / 6.0 : sin(half) / half;
            double chord = v * dt * sinc, mid = th + half;
            x += chord * cos(mid); y += chord * sin(mid); th += 2.0 * half;
            p[3 * (k + 1)] = x; p[3 * (k + 1) + 1] = y; p[3 * (k + 1) + 2] = th;
        }
    }
}
"""


def build_c_loop():
    """The C loop as a ctypes function, or None without a compiler."""
    compiler = shutil.which("cc") or shutil.which("gcc")
    if compiler is None:
        return None
    folder = Path(tempfile.mkdtemp())
    (folder / "loop.c").write_text(C_SOURCE)
    library = folder / "loop.so"
    subprocess.run(
        [compiler, "-O3", "-shared", "-fPIC", str(folder / "loop.c"), "-o", str(library), "-lm"],
        check=True,
    )
    function = ctypes.CDLL(str(library)).simulate_exact
    pointer = ctypes.POINTER(ctypes.c_double)
    function.argtypes = [pointer, ctypes.c_long, ctypes.c_long] + [ctypes.c_double] * 4 + [pointer]
    return function


def run_c_loop(function, robot, wheels, dt):
    robots, steps = (1, wheels.shape[0]) if wheels.ndim == 2 else wheels.shape[:2]
    poses = np.empty((robots, steps + 1, 3))
    as_pointer = np.ctypeslib.as_ctypes_type(np.float64)
    function(
        np.ascontiguousarray(wheels).ctypes.data_as(ctypes.POINTER(as_pointer)),
        robots,
        steps,
        dt,
        robot.left_wheel_radius,
        robot.right_wheel_radius,
        robot.track_width,
        poses.ctypes.data_as(ctypes.POINTER(as_pointer)),
    )
    return poses


def python_loop(robot, wheels, dt):
    x = y = th = 0.0
    poses = [(x, y, th)]
    for left, right in wheels.tolist():
        left, right = robot.left_wheel_radius * left, robot.right_wheel_radius * right
        v, om = 0.5 * (left + right), (right - left) / robot.track_width
        half = 0.5 * om * dt
        sinc = 1.0 - half * half / 6.0 if abs(half) < 1e-4 else math.sin(half) / half
        chord = v * dt * sinc
        x += chord * math.cos(th + half)
        y += chord * math.sin(th + half)
        th += 2.0 * half
        poses.append((x, y, th))
    return poses


def roboticstoolbox_loop():
    """``DiffSteer.deriv`` stepped with Euler, or None when roboticstoolbox is missing."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            from roboticstoolbox import DiffSteer
    except ImportError:
        return None

    def run(robot, wheels, dt):
        vehicle = DiffSteer(W=robot.track_width)
        pose = np.zeros(3)
        poses = [pose]
        for left, right in wheels * robot.wheel_radius:
            pose = pose + dt * vehicle.deriv(pose, (left, right), limits=False)
            poses.append(pose)
        return poses

    return run


def wpimath_loop():
    """``Pose2d.exp`` of each step's twist, or None when robotpy-wpimath is missing."""
    try:
        from wpimath.geometry import Pose2d, Twist2d
    except ImportError:
        return None

    def run(robot, wheels, dt):
        twists = dd.batch.to_twist(robot, wheels) * dt
        pose = Pose2d()
        poses = [pose]
        for dx, dy, dtheta in twists.tolist():
            pose = pose.exp(Twist2d(dx, dy, dtheta))
            poses.append(pose)
        return poses

    return run


def peak_memory_ratio(call, output_bytes):
    tracemalloc.start()
    call()
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return peak / output_bytes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--quick", action="store_true", help="10x smaller cases")
    args = parser.parse_args()
    scale = 10 if args.quick else 1
    robot = example_robot()
    dt = 1e-3
    loops = {
        "Python loop": (python_loop, 200_000),
        "roboticstoolbox": (roboticstoolbox_loop(), 20_000),
        "wpimath": (wpimath_loop(), 20_000),
    }
    c_loop = build_c_loop()
    import numba

    from diffdrive.backends.simulate_kernel import threads

    print(
        f"machine: {platform.machine()}, {platform.processor() or 'cpu'}, "
        f"{os.cpu_count()} cores; python {platform.python_version()}, numpy {np.__version__}, "
        f"numba {numba.__version__}; the kernel on {threads()} threads"
    )
    missing = [name for name, (loop, _) in loops.items() if loop is None]
    if c_loop is None:
        missing.append("C -O3 loop (no C compiler)")
    if missing:
        print(f"not installed, left out: {', '.join(missing)}")
    print(f"median of {args.repeats} runs; times in ns per robot-step\n")
    rng = np.random.default_rng(0)
    cases = [("1 x 1e7", (10**7 // scale, 2)), ("1e3 x 1e4", (1000, 10**4 // scale, 2))]
    for label, shape in cases:
        wheels = rng.uniform(-10.0, 10.0, shape)
        bench_case(label, robot, wheels, dt, c_loop, loops, args.repeats)
    if c_loop is not None:
        shared_machine(robot, dt, c_loop, 10**7 // scale, args.repeats)
    startup(args.repeats)


# Another process that keeps one core busy for as long as the parent lives.
_SPIN = "import os, sys\nwhile os.getppid() != 1: pass\n"


def shared_machine(robot, dt, c_loop, steps: int, repeats: int) -> None:
    """One robot's long run against the C loop, the two timed alternately: on an idle machine,
    then with another process spinning on one core (targets: at least 1.0x and 0.8x)."""
    import time

    wheels = np.random.default_rng(1).uniform(-10.0, 10.0, (steps, 2))
    contenders = {
        "diffdrive numba": lambda: dd.simulate(robot, wheels, dt=dt, backend="numba"),
        "C -O3 loop": lambda: run_c_loop(c_loop, robot, wheels, dt),
    }
    print(f"1 robot x {steps:.0e} steps, alternately, median of {repeats}:")
    for label, target in (("idle", 1.0), ("one core busy", 0.8)):
        spinner = None if label == "idle" else subprocess.Popen([sys.executable, "-c", _SPIN])
        try:
            times = {name: [] for name in contenders}
            for call in contenders.values():
                call()  # warm
            for _ in range(repeats):
                for name, call in contenders.items():
                    start = time.perf_counter()
                    call()
                    times[name].append(time.perf_counter() - start)
        finally:
            if spinner is not None:
                spinner.kill()
                spinner.wait()
        ours, theirs = (float(np.median(times[name])) for name in contenders)
        print(
            f"  {label:14} diffdrive {ours / steps * 1e9:6.1f} ns/step, C loop "
            f"{theirs / steps * 1e9:6.1f}: {theirs / ours:.2f}x the C loop's speed "
            f"(target {target:.1f}x)"
        )
    print()


# Run by a fresh process: seconds of its first kernel call (after importing diffdrive), and
# whether it imported numba.
_FIRST_CALL = """
import sys, time, numpy as np, diffdrive as dd
robot, wheels = dd.DiffDrive(0.05, 0.3), np.ones((1000, 2))
start = time.perf_counter()
dd.simulate(robot, wheels, dt=0.01, backend="numba")
print(time.perf_counter() - start, "numba" in sys.modules)
"""


def fresh_seconds(code: str, cache: str) -> tuple[float, str]:
    """What a fresh process running ``code`` prints, with the kernel's cache and numba's own
    in ``cache``: an empty one compiles everything, as on a fresh install."""
    env = {**os.environ, "DIFFDRIVE_CACHE_DIR": cache, "NUMBA_CACHE_DIR": cache}
    out = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
    ).stdout.split()
    return float(out[0]), " ".join(out[1:])


def startup(repeats: int) -> None:
    """The first call of fresh processes: compiling into an empty cache, then loading."""
    import statistics

    with tempfile.TemporaryDirectory() as cache:
        compiled, _ = fresh_seconds(_FIRST_CALL, cache)
        runs = [fresh_seconds(_FIRST_CALL, cache) for _ in range(repeats)]
        loads = [seconds for seconds, _ in runs]
        numba_imports = [
            fresh_seconds(
                "import time; t = time.perf_counter(); import numba; "
                "print(time.perf_counter() - t)",
                cache,
            )[0]
            for _ in range(repeats)
        ]
    load, numba_import = statistics.median(loads), statistics.median(numba_imports)
    print(f"start-up, fresh processes, median of {repeats}:")
    print(f"  first kernel call, cache on disk    {load:7.3f} s  (numba imported: {runs[0][1]})")
    print(f"  first kernel call, empty cache      {compiled:7.3f} s  (one run: it fills the cache)")
    print(
        f"  import numba alone                  {numba_import:7.3f} s  "
        f"({numba_import / load:.1f}x the cached first call)"
    )


def bench_case(label, robot, wheels, dt, c_loop, loops, repeats) -> None:
    """Time one case for every contender and print a row each, relative to diffdrive's numba."""
    robot_steps = wheels.size // 2

    def ours(backend):
        return lambda: dd.simulate(robot, wheels, dt=dt, backend=backend)

    row = {"diffdrive numba": median_time(ours("numba"), repeats, warm_up=True)}
    row["diffdrive NumPy"] = median_time(ours("numpy"), repeats, warm_up=True)
    expected = ours("numpy")().poses
    assert np.allclose(ours("numba")().poses, expected, rtol=0, atol=1e-9), "numba disagrees"
    if c_loop is not None:
        row["C -O3 loop"] = median_time(
            lambda: run_c_loop(c_loop, robot, wheels, dt), repeats, warm_up=True
        )
        check = run_c_loop(c_loop, robot, wheels, dt).reshape(expected.shape)
        assert np.allclose(check, expected, atol=1e-6), "the C loop disagrees with diffdrive"
    first_robot = wheels.reshape(-1, 2)
    for name, (loop, length) in loops.items():
        if loop is not None:
            sample = first_robot[:length]
            per_run = median_time(
                partial(loop, robot, sample, dt), max(1, repeats // 2), warm_up=True
            )
            row[name] = per_run / len(sample) * robot_steps
    output_bytes = (robot_steps + robot_steps // wheels.shape[-2]) * 3 * 8
    print(f"case {label}: peak memory / pose array:", end="")
    for backend in ("numba", "numpy"):
        print(f"  {backend} {peak_memory_ratio(ours(backend), output_bytes):.2f}", end="")
    print()
    ref = row["diffdrive numba"]
    for name, seconds in row.items():
        print(
            f"  {name:16} {seconds / robot_steps * 1e9:9.1f} ns/step   "
            f"diffdrive numba is {seconds / ref:7.2f} x as fast"
        )
    print()


if __name__ == "__main__":
    main()
