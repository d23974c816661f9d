"""Synthetic encoder throughput for 10^4 robots, side by side in one process.

Targets: at least 10^8 encoder samples a second without random noise (quantisation, roll-over,
biases, slips), and with wheel noise at most 1.5 times the time NumPy's own generator takes
to draw that noise alone. A sample is one wheel's reading at one instant. Prints the machine,
the median of several runs and the ratios.

    python benchmarks/bench_sensors.py [--robots 10000] [--steps 1000] [--repeats 5]
"""

from __future__ import annotations

import argparse
import dataclasses
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
    wheels = np.stack([6 + 4 * np.sin(0.7 * t[:-1]), 6 - 4 * np.cos(0.5 * t[:-1])], axis=-1)
    poses = dd.simulate(robot, wheels, times=t).poses
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

    def run(model):
        return lambda: sensors.encoder_readings(robot, t, poses, model, robots=args.robots, seed=1)

    def draw():
        rng.standard_normal((args.robots, args.steps, 2))

    for call in (run(plain), run(noisy), draw):  # once each before timing
        call()
    figures = {}
    for _ in range(args.repeats):  # in rounds: a slow spell of the machine falls on all
        for name, call in (("no noise", run(plain)), ("noise", run(noisy)), ("draw", draw)):
            figures.setdefault(name, []).append(median_seconds(call, 1))
    seconds = {name: float(np.median(values)) for name, values in figures.items()}
    print(
        f"machine: {platform.machine()}, {platform.processor() or 'cpu'}; python "
        f"{platform.python_version()}, numpy {np.__version__}"
    )
    print(f"{args.robots} robots x {args.steps + 1} samples x 2 wheels, median of {args.repeats}")
    for name, label in (("no noise", "without noise"), ("noise", "with noise")):
        rate = samples / seconds[name]
        print(f"  {label:14} {seconds[name]:.3f} s  {rate:.3g} samples/s")
    print(f"  NumPy's normals alone {seconds['draw']:.3f} s")
    extra = seconds["noise"] - seconds["no noise"]
    print(
        f"  the noise costs {extra:.3f} s, {extra / seconds['draw']:.2f}x NumPy's draw; the whole "
        f"noisy call is {seconds['noise'] / seconds['draw']:.2f}x the draw"
    )


if __name__ == "__main__":
    main()
