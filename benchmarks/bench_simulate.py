"""Simulation throughput, side by side in one process: diffdrive vs a C loop vs a Python loop.

Cases (issue 3): one robot over 10^7 steps, and 10^3 robots times 10^4 steps, with the exact
update. The C loop is compiled at -O3 from the source below when a C compiler is present and
called through ctypes on the same arrays. The Python loop is timed on a slice and reported per
step. Prints the median of several runs, the ratios, and the peak memory of diffdrive's call
relative to its output array.

    python benchmarks/bench_simulate.py [--repeats 5] [--quick]
"""

from __future__ import annotations

import argparse
import ctypes
import math
import platform
import shutil
import statistics
import subprocess
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np

import diffdrive as dd
from diffdrive.examples import example_robot

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


def median_time(call, repeats):
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        call()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


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
    c_loop = build_c_loop()
    print(
        f"machine: {platform.machine()}, {platform.processor() or 'cpu'}, "
        f"python {platform.python_version()}, numpy {np.__version__}"
    )
    print(f"median of {args.repeats} runs; times in ns per robot-step\n")
    rng = np.random.default_rng(0)
    cases = [("1 x 1e7", (10**7 // scale, 2)), ("1e3 x 1e4", (1000, 10**4 // scale, 2))]
    for label, shape in cases:
        bench_case(label, robot, rng.uniform(-10.0, 10.0, shape), dt, c_loop, args.repeats)


def bench_case(label, robot, wheels, dt, c_loop, repeats) -> None:
    """Time one case for every contender and print a row each, relative to diffdrive."""
    robot_steps = wheels.size // 2
    ours = median_time(lambda: dd.simulate(robot, wheels, dt=dt), repeats)
    row = {"diffdrive": ours}
    if c_loop is not None:
        row["C -O3 loop"] = median_time(lambda: run_c_loop(c_loop, robot, wheels, dt), repeats)
        expected = dd.simulate(robot, wheels, dt=dt).poses
        check = run_c_loop(c_loop, robot, wheels, dt).reshape(expected.shape)
        assert np.allclose(check, expected, atol=1e-6), "the C loop disagrees with diffdrive"
    sample = wheels.reshape(-1, 2)[:200_000]
    per_run = median_time(lambda: python_loop(robot, sample, dt), max(1, repeats // 2))
    row["Python loop"] = per_run / len(sample) * robot_steps
    output_bytes = (robot_steps + robot_steps // wheels.shape[-2]) * 3 * 8
    memory = peak_memory_ratio(lambda: dd.simulate(robot, wheels, dt=dt), output_bytes)
    print(f"case {label}: peak memory of diffdrive = {memory:.2f} x its pose array")
    for name, seconds in row.items():
        print(
            f"  {name:12} {seconds / robot_steps * 1e9:9.1f} ns/step   "
            f"diffdrive is {seconds / ours:7.2f} x as fast"
        )
    print()


if __name__ == "__main__":
    main()
