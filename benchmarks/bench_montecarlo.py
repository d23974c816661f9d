"""Monte Carlo, reduce-only: robot-steps per second in one process and on a Dask LocalCluster,
and the array libraries' whole-history rollout next to NumPy's.

Part 1 drives ``robots`` x ``steps`` robot-steps (default 10^6 x 10^3 = 10^9) with wheel noise
and geometry errors, keeping only the final poses and the per-step mean and covariance:
``monte_carlo`` on one thread, on two threads of one process, and ``diffdrive.distributed`` on
a LocalCluster of two single-threaded worker processes. The same seed and chunks, so the three
compute the same numbers. Part 2 times ``batch.rollout`` of 10^3 robots x 10^3 steps (float32)
in NumPy, PyTorch and JAX (jitted) on the CPU. Medians of several runs; the machine is printed.

    pip install -e '.[fast,dask]' jax torch
    python benchmarks/bench_montecarlo.py [--robots 1000000] [--steps 1000] [--repeats 3]
"""

from __future__ import annotations

import argparse
import os
import platform

import numpy as np

import diffdrive as dd
from diffdrive import batch, distributed
from diffdrive.montecarlo import monte_carlo
from timing import median_time  # benchmarks/timing.py

ROBOT = dd.DiffDrive(0.05, 0.3)
DT = 0.01
OPTIONS = {"wheel_noise": 1e-4, "geometry_sigma": (0.002, 0.002, 0.005), "seed": 1}


def history(steps: int) -> np.ndarray:
    t = np.arange(steps) * DT
    return np.stack([8 + 3 * np.sin(t), 8 - 3 * np.sin(0.7 * t)], axis=-1)


def monte_carlo_rates(robots: int, steps: int, repeats: int) -> dict[str, float]:
    from distributed import Client, LocalCluster

    wheels = history(steps)
    monte_carlo(ROBOT, wheels[:10], DT, 10, **OPTIONS)  # compile (or load) the kernel first
    seconds = {
        "one process, 1 thread": median_time(
            lambda: monte_carlo(ROBOT, wheels, DT, robots, **OPTIONS), repeats
        ),
        "one process, 2 threads": median_time(
            lambda: monte_carlo(ROBOT, wheels, DT, robots, threads=2, **OPTIONS), repeats
        ),
    }
    with (
        LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
        ) as cluster,
        Client(cluster) as client,
    ):
        distributed.monte_carlo(ROBOT, wheels[:10], DT, 10, client=client, **OPTIONS)  # warm up
        seconds["Dask, 2 worker processes"] = median_time(
            lambda: distributed.monte_carlo(ROBOT, wheels, DT, robots, client=client, **OPTIONS),
            repeats,
        )
    return seconds


def rollout_rates(repeats: int) -> dict[str, float]:
    """Seconds of one rollout of 10^3 robots x 10^3 steps, float32, per library (CPU)."""
    wheels = np.broadcast_to(history(1000), (1000, 1000, 2)).astype(np.float32)
    seconds = {"NumPy": median_time(lambda: batch.rollout(ROBOT, wheels, DT), repeats)}
    try:
        import torch

        on_torch = torch.asarray(wheels)
        seconds["PyTorch"] = median_time(lambda: batch.rollout(ROBOT, on_torch, DT), repeats)
    except ImportError:
        pass
    try:
        import jax

        on_jax = jax.numpy.asarray(wheels)
        jitted = jax.jit(batch.rollout, static_argnums=(0, 2))
        jitted(ROBOT, on_jax, DT).block_until_ready()  # compile first
        seconds["JAX (jit)"] = median_time(
            lambda: jitted(ROBOT, on_jax, DT).block_until_ready(), repeats
        )
    except ImportError:
        pass
    return seconds


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", type=int, default=1_000_000)
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args(argv)
    machine = platform.processor() or platform.machine()
    print(
        f"{machine}, {os.cpu_count()} cores, Python {platform.python_version()}, NumPy "
        f"{np.__version__}; medians of {args.repeats}"
    )
    total = args.robots * args.steps
    seconds = monte_carlo_rates(args.robots, args.steps, args.repeats)
    base = seconds["one process, 1 thread"]
    print(
        f"Monte Carlo, reduce-only, {args.robots} robots x {args.steps} steps = {total:.3g} "
        "robot-steps:"
    )
    for label, value in seconds.items():
        print(
            f"  {label}: {value:.1f} s, {total / value / 1e6:.1f} M robot-steps/s, "
            f"{base / value:.2f}x one thread"
        )
    rollout = rollout_rates(args.repeats)
    print("rollout of 10^6 robot-steps (10^3 x 10^3, float32), CPU:")
    for label, value in rollout.items():
        print(
            f"  {label}: {value * 1e3:.1f} ms, {1e6 / value / 1e6:.1f} M robot-steps/s, "
            f"{rollout['NumPy'] / value:.2f}x NumPy"
        )


if __name__ == "__main__":
    main()
