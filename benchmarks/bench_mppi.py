"""MPPI: one cycle's time, tracking through a known delay and lag, and cluttered corridors,
side by side with diffdrive's other trackers in one run.

Cycle: ``MPPI.command`` for one robot (sampling, rollouts through the drive's delay and lag,
every cost including a clearance grid, the update, the smoothing and the bookkeeping), the
median of repeated calls, at 2,048 x 100 and 16,384 x 100, by the compiled cycle and by each
array library installed (NumPy, PyTorch, JAX; on the CPU here). Nav2's MPPI takes 11.8 ms for
2,000 x 56 on a desktop i9 (navigation2#4352); the targets are half of what it takes for the
same sizes: 3.4 ms and 31 ms.

Tracking: plans followed with commands 0.1 s late through a 0.1 s first-order lag, both known
to the controller (``MPPI(drive=...)``; ``Predictive`` for the others), no noise, from the
plan's start, every 0.05 s. The scenarios: WPILib's LTVUnicycleControllerTest trajectory (as
in ``bench_planning.py``; 8.8 m/s, no wheel limit), and ``--paths`` random paths of 2-4
waypoints in an 8 m square planned at 1 m/s, 1 m/s^2 and 10 rad/s a wheel on a robot of 0.1 m
wheels and 0.6 m track whose wheels reach 12 rad/s (MPPI's limit). Printed per tracker: mean
and maximum cross-track error, and the largest wheel velocity against the limit.

Obstacles: ``--runs`` seeded corridors (``control.cluttered_corridor``: 12 m x 3 m, 8 circles
of radius 0.15-0.4 m, a way through for a robot of radius 0.45 m), a straight plan from one end
to the other at 1 m/s (wheels 12 rad/s), the robot of radius 0.35 m, the same delay and lag.
Counted: runs that touch (judged on the exact circles and walls), runs that do not reach the
goal within 0.05 m (each run simulated until the guide's plan ends and 2 s more, at least
1.5 times the straight plan), and the time to the goal against the straight plan's. Side by
side, on the first ``--compare`` seeds: MPPI on the plan as given (no guide), and
Predictive(Ramsete) on the guide's plan (no obstacle costs).

Busy: the compiled cycle with one core kept busy by another process, on the cores it finds
free against forced onto one thread (twice, for the noise between two runs of one cycle), a
cycle of each in turn; then forced onto every thread.

Robots and rates: three robots the controller was not tuned on (``OTHERS``: the issue's 0.075
m wheels with 12 V through a feedforward, the tracking robot given a drive, a Husky-sized
one), at 20, 50 and 100 ms, ``--other-paths`` random paths planned at 90 % of each wheel
limit, the same delay and lag: cross-track mean and max, periods with a wheel past a limit by
over 1 %, the end's distance 1 s after the plan, and CPU time per period, MPPI (defaults, the
robot's ``WheelLimits``) beside Predictive(LTVUnicycle). And ``--other-runs`` corridors on each
of them at each period (the footprint theirs, the straight plan at 90 % of their limits):
touched, goal missed, stalls found, periods past a limit, time to the goal against the
straight plan; run a process per core, each cycle on one thread.

    python benchmarks/bench_mppi.py [--runs 1000] [--paths 20] [--repeats 15]
        [--other-paths 10] [--other-runs 200] [--libraries numba numpy torch jax]
"""

from __future__ import annotations

import argparse
import importlib.util
import platform
import subprocess
import sys
import time

import numpy as np

import diffdrive as dd
from bench_planning import random_waypoints  # benchmarks/bench_planning.py
from diffdrive.control import (
    MPPI,
    Avoidance,
    FollowSettings,
    LTVUnicycle,
    MPPISampling,
    PathLimits,
    Predictive,
    PurePursuit,
    Ramsete,
    WheelLimits,
    cluttered_corridor,
    follow,
    guide,
    plan,
)
from diffdrive.dynamics import DriveModel, Feedforward

ROBOT = dd.DiffDrive(wheel_radius=0.1, track_width=0.6)
DT, DELAY, LAG, WHEELS = 0.05, 0.1, 0.1, 12.0
GOAL = 0.05  # m: the goal counts as reached within it
DRIVE = DriveModel(delay=DELAY, time_constant=LAG)
FOOTPRINT = 0.35


_START = np.array([[0.0, 0.0, 0.0]])  # the pose every timed cycle is given


def _cycle_tracker(samples: int, backend: str) -> tuple[MPPI, object]:
    """A tracker on the benchmark's corridor after a first cycle (which compiles and makes
    the guide), and the plan it follows."""
    course = cluttered_corridor(np.random.default_rng(3), footprint=FOOTPRINT)
    path = plan([course.start, course.goal], ROBOT, PathLimits(1.0, 1.0, max_wheel_velocity=12))
    tracker = MPPI(
        drive=DRIVE,
        backend=backend,
        sampling=MPPISampling(samples=samples, horizon=100 * DT, seed=0),
        avoid=Avoidance(course.obstacles, footprint=FOOTPRINT),
    )
    tracker.command(path, 0.0, _START)
    return tracker, path


def _timed_cycle(tracker: MPPI, path, k: int) -> tuple[float, float]:
    """Wall and CPU time (s) of the tracker's cycle ``k`` (from 1, a period apart)."""
    wall, cpu = time.perf_counter(), time.process_time()
    tracker.command(path, DT * k, _START)
    return time.perf_counter() - wall, time.process_time() - cpu


def _medians(times: list[tuple[float, float]]) -> tuple[float, float]:
    """Median wall and CPU time (ms)."""
    walls, cpus = zip(*times, strict=True)
    return 1e3 * float(np.median(walls)), 1e3 * float(np.median(cpus))


def _cycle_time(samples: int, backend: str, count: int) -> tuple[float, float]:
    """Median wall and CPU time (ms) of one cycle, after a first that compiles."""
    tracker, path = _cycle_tracker(samples, backend)
    return _medians([_timed_cycle(tracker, path, k + 1) for k in range(count)])


def cycle_times(repeats: int, libraries: list[str]) -> None:
    print("one MPPI cycle (one robot, clearance grid on; median wall / CPU):")
    for samples in (2048, 16384):
        for backend in libraries:
            if backend in ("torch", "jax") and samples > 2048:
                continue
            count = repeats if backend == "numba" else min(repeats, 3)
            wall, cpu = _cycle_time(samples, backend, count)
            print(f"  {samples:,} x 100, {backend}: {wall:.2f} / {cpu:.2f} ms")


def _forced_cycles(
    samples: int, modes: dict[str, int | None], repeats: int
) -> dict[str, tuple[float, float]]:
    """Median wall and CPU time (ms) of a tracker per mode (its threads; None: the free-core
    rule), a cycle of each in turn, the order reversed every other round so that each mode
    follows the others as often."""
    from diffdrive.backends import numba_mppi

    free = numba_mppi.free_threads
    runs = {label: _cycle_tracker(samples, "numba") for label in modes}
    times: dict[str, list[tuple[float, float]]] = {label: [] for label in modes}
    for k in range(repeats):
        for label in list(modes)[:: 1 if k % 2 else -1]:
            threads = modes[label]
            if threads is not None:
                numba_mppi.free_threads = lambda threads=threads: threads
            try:
                times[label].append(_timed_cycle(*runs[label], k + 1))
            finally:
                numba_mppi.free_threads = free
    return {label: _medians(times[label]) for label in modes}


def busy_cycle_times(repeats: int) -> None:
    """The compiled cycle with one core kept busy by another process: on the cores it finds
    free against forced onto one thread (twice: the noise between two runs of the same cycle),
    side by side; then forced onto every thread, apart (a cycle just after one on every
    thread runs slower while that one's threads spin)."""
    import numba

    every = numba.config.NUMBA_NUM_THREADS
    busy = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        time.sleep(1.0)
        print(f"one MPPI cycle with one of {every} cores busy (median wall / CPU):")
        for samples in (2048, 16384):
            # One thread twice: how far two runs of the same cycle differ here.
            paired = {"free cores": None, "one thread": 1, "one thread again": 1}
            medians = _forced_cycles(samples, paired, repeats)
            medians |= _forced_cycles(samples, {"every thread": every}, repeats)
            row = "; ".join(f"{label} {w:.2f} / {c:.2f} ms" for label, (w, c) in medians.items())
            print(f"  {samples:,} x 100: {row}")
    finally:
        busy.kill()
        busy.wait()


def trackers(wheels: float | None) -> dict[str, object]:
    """Each tracker's maker; ``wheels``: MPPI's wheel limit (rad/s; None: the plan's)."""
    return {
        "MPPI (delay and lag known)": lambda: MPPI(
            drive=DRIVE,
            limits=WheelLimits(max_velocity=wheels),
            sampling=MPPISampling(seed=1),
        ),
        "Ramsete": Ramsete,
        "LTVUnicycle": lambda: LTVUnicycle(dt=DT),
        "PurePursuit": PurePursuit,
        "Predictive(Ramsete)": lambda: Predictive(Ramsete(), DELAY, DT, LAG),
        "Predictive(LTVUnicycle)": lambda: Predictive(LTVUnicycle(dt=DT), DELAY, DT, LAG),
    }


def tracking(paths: int) -> None:
    wpilib = plan([(2.75, 22.521, 0.0), (24.73, 19.68, 5.846)], ROBOT,
                  PathLimits(max_velocity=8.8, max_acceleration=0.1))  # fmt: skip
    rng = np.random.default_rng(1)
    limits = PathLimits(max_velocity=1.0, max_acceleration=1.0, max_wheel_velocity=10.0)
    randoms = [plan(random_waypoints(rng), ROBOT, limits) for _ in range(paths)]
    print(f"tracking with {DELAY} s delay and {LAG} s lag (cross-track mean / max, mm):")
    for name in trackers(None):
        row = []
        for label, plans in (("WPILib's 30 s", [wpilib]), (f"{paths} random paths", randoms)):
            make = trackers(None if label.startswith("WPILib") else WHEELS)[name]
            cross, wheels = [], 0.0
            for reference in plans:
                result = follow(reference, make(), dt=DT, drive=DRIVE)
                cross.append(np.abs(result.errors().cross_track).ravel())
                wheels = max(wheels, float(np.abs(result.wheel_velocities).max()))
            every = np.concatenate(cross)
            limit = "" if label.startswith("WPILib") else f", wheels {wheels:.2f} of {WHEELS:g}"
            row.append(f"{label} {1e3 * every.mean():.1f} / {1e3 * every.max():.1f}{limit}")
        print(f"  {name}: " + "; ".join(row))


def corridor_outcome(course, straight, reference, tracker, footprint: float, period: float):
    """``tracker`` driving ``reference`` through ``course`` at ``period`` s, until the guide's
    way around ends and 2 s more (at least 1.5 times the ``straight`` plan): whether it
    touched, its time to the goal against the straight plan (None: not reached), the
    guide's own plan against it, and the run."""
    way = guide(straight, course.obstacles, footprint).duration
    settle = FollowSettings(settle=max(0.5 * straight.duration, way - straight.duration + 2.0))
    result = follow(reference, tracker, dt=period, drive=DRIVE, settings=settle)
    poses = result.poses[0]
    reached = np.flatnonzero(np.hypot(*(poses[:, :2] - course.goal[:2]).T) < GOAL)
    first = result.times[reached[0]] - result.times[0] if len(reached) else None
    return {
        "touch": bool(course.touches(poses, footprint).any()),
        "ratio": None if first is None else first / straight.duration,
        "guide": way / straight.duration,
        "result": result,
    }


def _seeds(*lists: tuple[str, list[int]]) -> None:
    """Print each non-empty list of seeds under its label."""
    for label, seeds in lists:
        if seeds:
            print(f"    {label}: seeds {seeds[:12]}{' ...' if len(seeds) > 12 else ''}")


def corridor_run(seed: int, kind: str) -> dict[str, object]:
    course = cluttered_corridor(np.random.default_rng(seed), footprint=FOOTPRINT)
    limits = PathLimits(max_velocity=1.0, max_acceleration=1.0, max_wheel_velocity=WHEELS)
    straight = plan([course.start, course.goal], ROBOT, limits)
    if kind == "Predictive(Ramsete) on the guide":
        tracker = Predictive(Ramsete(), DELAY, DT, LAG)
        reference = guide(straight, course.obstacles, FOOTPRINT)
    else:
        tracker = MPPI(
            drive=DRIVE,
            sampling=MPPISampling(seed=seed),
            avoid=Avoidance(course.obstacles, footprint=FOOTPRINT, around=kind == "MPPI"),
        )
        reference = straight
    outcome = corridor_outcome(course, straight, reference, tracker, FOOTPRINT, DT)
    del outcome["result"]
    return outcome


def obstacles(runs: int, compare: int) -> None:
    print(f"cluttered corridors, {DELAY} s delay and {LAG} s lag:")
    for kind, count in (("MPPI", runs), ("MPPI, no guide", compare),
                        ("Predictive(Ramsete) on the guide", compare)):  # fmt: skip
        start = time.perf_counter()
        outcomes = [corridor_run(seed, kind) for seed in range(count)]
        touched = [s for s, o in enumerate(outcomes) if o["touch"]]
        missed = [s for s, o in enumerate(outcomes) if o["ratio"] is None]
        ratios = np.array([o["ratio"] for o in outcomes if o["ratio"] is not None])
        slow = [s for s, o in enumerate(outcomes) if o["ratio"] is not None and o["ratio"] > 1.3]
        spread = (f"time to goal / straight plan: median {np.median(ratios):.3f}, 99th "
                  f"percentile {np.percentile(ratios, 99):.3f}, max {ratios.max():.3f}"
                  if len(ratios) else "no run reached the goal")  # fmt: skip
        print(
            f"  {kind}, {count} runs ({time.perf_counter() - start:.0f} s): touched "
            f"{len(touched)}, goal missed {len(missed)}, over 1.3x {len(slow)}; {spread}"
        )
        _seeds(("touched", touched), ("missed", missed), ("over 1.3x", slow))


# Robots the controller was not tuned on: (robot, wheel limits, footprint m). The issue's: a
# 50 Hz loop's robot with 12 V through a feedforward; the tracking benchmark's robot given a
# drive; a Husky-sized one, slow and heavy.
OTHERS = {
    "0.075 m wheels, 0.38 m track": (
        dd.DiffDrive(wheel_radius=0.075, track_width=0.38),
        WheelLimits(14.0, 20.0, 12.0, Feedforward(0.5, 0.78, 0.06)),
        0.25,
    ),
    "0.1 m wheels, 0.6 m track": (
        dd.DiffDrive(wheel_radius=0.1, track_width=0.6),
        WheelLimits(12.0, 15.0, 24.0, Feedforward(0.3, 1.2, 0.1)),
        0.35,
    ),
    "0.165 m wheels, 0.555 m track": (
        dd.DiffDrive(wheel_radius=0.165, track_width=0.555),
        WheelLimits(6.0, 6.0, 24.0, Feedforward(1.0, 3.0, 0.4)),
        0.4,
    ),
}
PERIODS = (0.02, 0.05, 0.1)
SHARE = 0.9  # the plans use 90 % of each wheel limit


def planned_within(limits: WheelLimits) -> PathLimits:
    """The plan's limits: ``SHARE`` of the wheels'."""
    assert limits.max_velocity is not None
    assert limits.max_acceleration is not None
    assert limits.max_voltage is not None
    return PathLimits(
        max_wheel_velocity=SHARE * limits.max_velocity,
        max_wheel_acceleration=SHARE * limits.max_acceleration,
        max_voltage=SHARE * limits.max_voltage,
        feedforward=limits.feedforward,
    )


def over_limits(result, limits: WheelLimits, period: float) -> int:
    """Periods in which a wheel's velocity, acceleration or voltage is past its limit by more
    than 1 %."""
    wheels = result.wheel_velocities[0]
    acceleration = np.diff(wheels, axis=0) / period
    (ff, _) = limits.feedforwards()
    assert ff is not None
    assert limits.max_voltage is not None
    moving = np.where(wheels[1:] != 0.0, wheels[1:], wheels[:-1])
    volts = ff.ks * np.sign(moving) + ff.kv * wheels[1:] + ff.ka * acceleration
    past = (np.abs(wheels[1:]) > 1.01 * limits.max_velocity).any(axis=1)
    past |= (np.abs(acceleration) > 1.01 * limits.max_acceleration).any(axis=1)
    past |= (np.abs(volts) > 1.01 * limits.max_voltage).any(axis=1)
    return int(past.sum())


def robots_and_rates(paths: int) -> None:
    """Each robot of ``OTHERS`` at each period of ``PERIODS``: random paths planned at 90 % of
    its limits, followed 1 s past their end behind 0.1 s of delay and a 0.1 s lag known to
    the trackers (MPPI with its defaults and the robot's limits; Predictive(LTVUnicycle))."""
    print(
        f"robots and rates: {paths} random paths each, planned at {SHARE:.0%} of the wheels' "
        "limits, 0.1 s delay and 0.1 s lag known (cross-track mean / max mm, periods over a "
        "limit, largest end distance mm 1 s after the plan, CPU per period ms):"
    )
    for name, (robot, limits, _) in OTHERS.items():
        for period in PERIODS:
            makers = {
                "MPPI": lambda period=period, limits=limits: MPPI(
                    dt=period, drive=DRIVE, limits=limits, sampling=MPPISampling(seed=1)
                ),
                "Predictive(LTVUnicycle)": lambda period=period: Predictive(
                    LTVUnicycle(dt=period), DELAY, period, LAG
                ),
            }
            for label, make in makers.items():
                rng = np.random.default_rng(1)
                cross, over, ends, cpu = [], 0, [], []
                for _ in range(paths):
                    reference = plan(random_waypoints(rng), robot, planned_within(limits))
                    start = time.process_time()
                    result = follow(reference, make(), dt=period, drive=DRIVE)
                    cpu.append((time.process_time() - start) / len(result.times))
                    cross.append(np.abs(result.errors().cross_track).ravel())
                    over += over_limits(result, limits, period)
                    ends.append(np.hypot(*(result.poses[0, -1, :2] - reference.poses[-1, :2])))
                every = np.concatenate(cross)
                print(
                    f"  {name}, {1e3 * period:.0f} ms, {label}: {1e3 * every.mean():.1f} / "
                    f"{1e3 * every.max():.1f} mm, over {over}, end {1e3 * max(ends):.1f} mm, "
                    f"{1e3 * np.median(cpu):.1f} ms"
                )


def corridor_on_robot(name: str, period: float, seed: int) -> dict[str, object]:
    """One corridor of ``seed`` for robot ``name`` of ``OTHERS`` at ``period`` s: MPPI with
    its defaults and the robot's limits, on the straight plan at 90 % of them."""
    robot, limits, footprint = OTHERS[name]
    course = cluttered_corridor(np.random.default_rng(seed), footprint=footprint)
    straight = plan([course.start, course.goal], robot, planned_within(limits))
    tracker = MPPI(
        dt=period,
        drive=DRIVE,
        limits=limits,
        sampling=MPPISampling(seed=seed),
        avoid=Avoidance(course.obstacles, footprint=footprint),
    )
    outcome = corridor_outcome(course, straight, straight, tracker, footprint, period)
    result = outcome.pop("result")
    return {**outcome, "stalls": len(tracker.stalls), "over": over_limits(result, limits, period)}


def _one_thread_corridor(task: tuple[str, float, int]) -> dict[str, object]:
    return corridor_on_robot(*task)


def corridors_on_robots(runs: int) -> None:
    """``runs`` corridors for each robot of ``OTHERS`` at each period of ``PERIODS``, spread
    over a process per core, each cycle on one thread (only outcomes are counted here)."""
    import multiprocessing
    import os

    print(
        f"cluttered corridors on each robot and period, {runs} runs each, MPPI with its "
        "defaults, planned at 90 % of the limits, 0.1 s delay and lag known:"
    )
    os.environ["NUMBA_NUM_THREADS"] = "1"  # read by the workers as they start
    with multiprocessing.get_context("spawn").Pool(os.cpu_count()) as pool:
        for name in OTHERS:
            for period in PERIODS:
                start = time.perf_counter()
                tasks = [(name, period, seed) for seed in range(runs)]
                outcomes = pool.map(_one_thread_corridor, tasks)
                touched = [s for s, o in enumerate(outcomes) if o["touch"]]
                missed = [s for s, o in enumerate(outcomes) if o["ratio"] is None]
                ratios = np.array([o["ratio"] for o in outcomes if o["ratio"] is not None])
                slow = int(np.count_nonzero(ratios > 1.3))
                stalls = sum(int(o["stalls"]) for o in outcomes)  # type: ignore[call-overload]
                over = sum(int(o["over"]) for o in outcomes)  # type: ignore[call-overload]
                guides = np.mean([o["guide"] for o in outcomes])
                spread = (
                    f"time / straight plan median {np.median(ratios):.3f}, mean "
                    f"{ratios.mean():.3f} (the guide's own plan {guides:.3f}), max "
                    f"{ratios.max():.3f}, over 1.3x {slow}"
                    if len(ratios)
                    else "no run reached the goal"
                )
                print(
                    f"  {name}, {1e3 * period:.0f} ms ({time.perf_counter() - start:.0f} s): "
                    f"touched {len(touched)}, goal missed {len(missed)}, stalls {stalls}, "
                    f"periods over a limit {over}; {spread}"
                )
                _seeds(("touched", touched), ("missed", missed))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=1000)
    parser.add_argument("--compare", type=int, default=100)
    parser.add_argument("--paths", type=int, default=20)
    parser.add_argument("--repeats", type=int, default=15)
    parser.add_argument("--other-paths", type=int, default=10,
                        help="random paths per robot and period in robots_and_rates")  # fmt: skip
    parser.add_argument("--other-runs", type=int, default=200,
                        help="corridors per robot and period in corridors_on_robots")  # fmt: skip
    installed = ["numba", "numpy"] + [n for n in ("torch", "jax") if importlib.util.find_spec(n)]
    parser.add_argument("--libraries", nargs="+", default=installed, choices=installed,
                        help="the cycle's back ends (default: every one installed)")  # fmt: skip
    args = parser.parse_args()
    print(f"machine: {platform.processor() or platform.machine()}, {platform.python_version()}")
    cycle_times(args.repeats, args.libraries)
    if "numba" in args.libraries:
        busy_cycle_times(args.repeats)
    tracking(args.paths)
    robots_and_rates(args.other_paths)
    obstacles(args.runs, args.compare)
    corridors_on_robots(args.other_runs)


if __name__ == "__main__":
    main()
