"""How many labelled slipping intervals the gyro's slip tests find, and how many others they flag.

Synthetic runs from ``diffdrive.sensors``: a robot of 0.05 m wheels and a 0.3 m track drives
40 s at 50 Hz along a winding path (each wheel between 2 and 10 rad/s), its wheels with
random-walk noise ``k`` = 1e-5 m, its gyro with an angle random walk of 2e-3 rad/s/sqrt(Hz).
Each robot slips in five episodes of 0.4 s at random times, on a random wheel; each slip
ratio is one row. The whole log runs through ``gyro_odometry`` (heading ``"fused"``, the bias
estimated), once with the streaming per-interval test alone (``slip_test="interval"``) and
once with the slip episodes as well (the default). Target: at least 99 % of the slipping
intervals found, and false alarms at the default threshold's 0.1 % within sampling noise.

    python benchmarks/bench_slip_detection.py [--robots 50] [--ratios 0.5 0.2 0.1 -0.33]
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import platform

import numpy as np

import diffdrive as dd
from diffdrive import sensors
from diffdrive.estimation import EstimatorSettings, Gyro, WholeLog, gyro_odometry
from diffdrive.sensor_noise import DEFAULT_GYRO, GyroNoise

ROBOT = dd.DiffDrive(wheel_radius=0.05, track_width=0.3)
K, ARW = 1e-5, 2e-3
TIMES = np.arange(2001) * 0.02


def path() -> np.ndarray:
    t = TIMES[:-1]
    wheels = np.stack([6 + 4 * np.sin(0.7 * t), 6 - 4 * np.cos(0.5 * t)], axis=-1)
    return dd.simulate(ROBOT, wheels, times=TIMES).poses


def episodes(rng: np.random.Generator, ratio: float) -> tuple[sensors.Slip, ...]:
    """Five 0.4 s episodes, at least 2 s apart, on a random wheel each."""
    starts = 1.0 + np.sort(rng.choice(np.arange(0, 36, 2.4), 5, replace=False))
    starts += rng.uniform(0.0, 1.0, 5)
    wheels = rng.choice(["left", "right"], 5)
    return tuple(sensors.Slip(s, s + 0.4, w, ratio) for s, w in zip(starts, wheels, strict=True))


def detection(poses: np.ndarray, ratio: float, robots: int) -> dict[str, tuple[int, int, int, int]]:
    """Per slip test: slipping intervals found, slipping intervals, others flagged, others."""
    rng = np.random.default_rng(17)
    counts = {"interval": [0, 0, 0, 0], "episodes": [0, 0, 0, 0]}
    noise = dataclasses.replace(DEFAULT_GYRO, angle_random_walk=ARW)
    for n in range(robots):
        slips = episodes(rng, ratio) if ratio else ()
        model = sensors.EncoderModel(wheel_noise=K, slips=slips)
        encoders = sensors.encoder_readings(ROBOT, TIMES, poses, model, seed=100 + n)
        gyro = sensors.gyro_readings(
            ROBOT,
            TIMES,
            poses,
            sensors.GyroModel(noise=GyroNoise(angle_random_walk=ARW)),
            seed=200 + n,
        )
        labelled = encoders.slipping[0].any(axis=1)
        for test, tally in counts.items():
            result = gyro_odometry(
                ROBOT,
                TIMES,
                np.diff(encoders.readings[0], axis=0),
                Gyro(TIMES, gyro.rates[0]),
                EstimatorSettings(
                    bias=0.0,
                    wheel_noise=K,
                    gyro_noise=noise,
                    whole_log=WholeLog(slip_episodes=test == "episodes"),
                ),
            )
            flagged = result.slip[1:]
            tally[0] += int(np.count_nonzero(flagged & labelled))
            tally[1] += int(labelled.sum())
            tally[2] += int(np.count_nonzero(flagged & ~labelled))
            tally[3] += int(np.count_nonzero(~labelled))
    return {test: tuple(tally) for test, tally in counts.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", type=int, default=50)
    parser.add_argument("--ratios", type=float, nargs="+", default=[0.5, 0.2, 0.1, -0.33, 0.0])
    args = parser.parse_args()
    poses = path()
    print(f"machine: {platform.machine()}; python {platform.python_version()}")
    print(f"{args.robots} robots x 2000 intervals, k = {K:g} m, angle random walk {ARW:g}")
    print("ratio | per-interval test: found, false alarms | with episodes: found, false alarms")
    for ratio in args.ratios:
        row = detection(poses, ratio, args.robots)
        cells = []
        for found, slipping, alarms, others in row.values():
            share = f"{100 * found / slipping:.2f} %" if slipping else "-"
            # the binomial standard deviation of the false-alarm share at the stated 0.1 %
            spread = 100 * math.sqrt(0.001 * 0.999 / others)
            cells.append(f"{share}, {100 * alarms / others:.3f} % (+-{spread:.3f})")
        print(f"{ratio:+.2f} | {cells[0]} | {cells[1]}")


if __name__ == "__main__":
    main()
