"""Synthetic encoder throughput for 10^4 robots, side by side in one process.

Two batches: every robot on one shared trajectory, and 10^4 different trajectories (the
compiled kernel, where numba is installed). Targets: at least 10^8 encoder samples a second
without random noise (quantisation, roll-over, biases, slips), and with wheel noise at most
1.5 times the time NumPy's own generator takes to draw that noise alone. A sample is one
wheel's reading at one instant. Prints the machine, the median of several runs (taken in
rounds, every contender once a round) and the ratios.

    python benchmarks/bench_sensors.py [--robots 10000] [--steps 1000] [--repeats 5]
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import time

import numpy as np

import diffdrive as dd
from diffdrive import sensors


def median_seconds(call, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        call()
        times.append(time.perf_counter() - start)
    return float(np.median(times))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", type=int, default=10_000)
    parser.add_argument("--steps", type=int, default=1_000)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    robot = dd.DiffDrive(0.05, 0.3)
    t = np.arange(args.steps + 1) * 0.02
    rate = np.random.default_rng(2).uniform(0.3, 1.0, (args.robots, 1))  # each robot its own
    wheels = np.stack([6 + 4 * np.sin(rate * t[:-1]), 6 - 4 * np.cos(0.7 * rate * t[:-1])], -1)
    different = dd.simulate(robot, wheels, times=t).poses  # (robots, steps + 1, 3)
    shared = different[0]
    slips = (sensors.Slip(t[-1] * 0.3, t[-1] * 0.4, "left", 0.5),)
    plain = sensors.EncoderModel(
        ticks_per_revolution=4096,
        counter_bits=16,
        radius_bias=(0.01, -0.01),
        track_bias=0.02,
        slips=slips,
    )
    noisy = dataclasses.replace(plain, wheel_noise=1e-4)
    samples = args.robots * (args.steps + 1) * 2
    rng = np.random.default_rng(0)

    def run(poses, model):
        return lambda: sensors.encoder_readings(robot, t, poses, model, robots=args.robots, seed=1)

    def draw():
        rng.standard_normal((args.robots, args.steps, 2))

    contenders = {
        "shared, no noise": run(shared, plain),
        "shared, noise": run(shared, noisy),
        "different, no noise": run(different, plain),
        "different, noise": run(different, noisy),
        "draw": draw,
    }
    for call in contenders.values():  # once each before timing (the kernel compiles or loads)
        call()
    figures: dict[str, list[float]] = {}
    for _ in range(args.repeats):  # in rounds: a slow spell of the machine falls on all
        for name, call in contenders.items():
            figures.setdefault(name, []).append(median_seconds(call, 1))
    seconds = {name: float(np.median(values)) for name, values in figures.items()}
    print(
        f"machine: {platform.machine()}, {platform.processor() or 'cpu'}, {os.cpu_count()} "
        f"cores; python {platform.python_version()}, numpy {np.__version__}"
    )
    print(f"{args.robots} robots x {args.steps + 1} samples x 2 wheels, median of {args.repeats}")
    print(f"  NumPy's normals alone           {seconds['draw']:.3f} s")
    for batch in ("shared", "different"):
        quiet, loud = seconds[f"{batch}, no noise"], seconds[f"{batch}, noise"]
        print(
            f"  {batch + ' trajectories,':24} without noise {quiet:.3f} s "
            f"({samples / quiet:.3g} samples/s; target 1e8), with noise {loud:.3f} s "
            f"({loud / seconds['draw']:.2f}x the draw; target 1.5x)"
        )


if __name__ == "__main__":
    main()
