"""Monte Carlo over robots without storing their paths: final poses and running statistics.

``monte_carlo`` drives ``robots`` copies of a robot through one nominal history of wheel
velocities ``(T, 2)``, each with its own errors, and keeps only each robot's final pose
``(N, 3)`` and, per step, the mean ``(T+1, 3)`` and covariance ``(T+1, 3, 3)`` of the poses over
the robots. Memory is ``N x 3`` plus ``T x 12`` plus one block of ``chunk x block`` poses, so
10^9 robot-steps fit in a laptop's memory.

The errors are those of ``Odometry``'s covariance model, so that the two can be compared:

- each step's wheel travel ``ds`` (m) gets Gaussian noise of variance ``k |ds|`` with each
  wheel's ``k`` of ``wheel_noise`` (a ``WheelNoise``, m; ``diffdrive.sensor_noise``; none by
  default);
- each robot's wheel radii and track width are the nominal ones times ``1 + e``, with ``e``
  Gaussian of the relative standard deviations ``geometry_sigma`` (a calibration's
  uncertainty), fixed over the run.

Robots are drawn in chunks of ``chunk``; chunk ``i`` takes its random numbers from child ``i``
of ``numpy.random.SeedSequence(seed)``. So a result depends on the seed, the chunk size and the
backend (``"numba"``, a compiled loop that folds each pose into the statistics as it goes, or
``"numpy"``, blocked prefix sums; ``"auto"``: numba when installed), not on how the chunks are
shared out: ``threads`` run chunks side by side in this process, and ``diffdrive.distributed``
runs them on Dask workers; both merge the statistics (Chan et al.'s pairwise update) to the
same numbers, to rounding.
"""

from __future__ import annotations

import functools
import importlib.util
import math
from collections.abc import Iterable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Literal

import numpy as np

from diffdrive._arrays import components
from diffdrive._validate import finite, whole
from diffdrive.batch.integration import accumulate, twists
from diffdrive.batch.kinematics import WHEELS
from diffdrive.batch.se2 import POSE
from diffdrive.integrate import Method, check_method
from diffdrive.model import DiffDrive, geometry_of
from diffdrive.sensor_noise import NONE as NO_NOISE
from diffdrive.sensor_noise import WheelNoise, WheelNoiseLike, draw_geometry, draw_travel

__all__ = [
    "Experiment",
    "Moments",
    "MonteCarlo",
    "checked_result",
    "experiment",
    "monte_carlo",
    "run_chunks",
]

Backend = Literal["auto", "numpy", "numba"]
BACKENDS: tuple[Backend, ...] = ("auto", "numpy", "numba")
CHUNK = 4096  # robots drawn together
_BLOCK_ELEMENTS = 1 << 20  # robot-steps of one block in memory


@dataclass(frozen=True)
class Moments:
    """Per-step statistics over ``count`` robots: ``mean`` ``(T+1, 3)`` and the sums of squared
    deviations ``m2`` ``(T+1, 3, 3)`` (the covariance times ``count - 1``)."""

    count: int
    mean: np.ndarray
    m2: np.ndarray

    def merge(self, other: Moments) -> Moments:
        """The statistics of both sets of robots together (Chan, Golub and LeVeque, 1979)."""
        count = self.count + other.count
        delta = other.mean - self.mean
        mean = self.mean + delta * (other.count / count)
        shift = np.einsum("ti,tj->tij", delta, delta) * (self.count * other.count / count)
        return Moments(count, mean, self.m2 + other.m2 + shift)

    @staticmethod
    def combine(parts: Iterable[Moments]) -> Moments:
        """The statistics of all the parts' robots together, merged in order."""
        return functools.reduce(Moments.merge, parts)


@dataclass(frozen=True)
class MonteCarlo:
    """The result: ``final`` poses ``(N, 3)``, per-step ``mean`` ``(T+1, 3)`` and
    ``covariance`` ``(T+1, 3, 3)`` over the robots (m, rad; headings unwrapped)."""

    final: np.ndarray
    moments: Moments

    @property
    def mean(self) -> np.ndarray:
        """The robots' mean final pose ``(3,)``."""
        return self.moments.mean

    @property
    def covariance(self) -> np.ndarray:
        """Unbiased (divided by ``N - 1``); NaN with a single robot."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return self.moments.m2 / (self.moments.count - 1)

    def quantiles(self, q: object) -> np.ndarray:
        """Quantiles ``q`` (in [0, 1]) of the final poses, each component: ``(len(q), 3)``."""
        return np.quantile(self.final, np.asarray(q, dtype=float), axis=0)


@dataclass(frozen=True)
class Experiment:
    """A checked experiment, shared by every chunk (and sent to every Dask worker); ``seed`` is
    fixed here, drawn from the system when none was given, so that every chunk agrees."""

    robot: DiffDrive
    travel: np.ndarray  # (T, 2) nominal wheel angles turned per step, rad
    start: np.ndarray  # (3,)
    k: np.ndarray  # (2,) m
    geometry_sigma: np.ndarray  # (3,) relative
    method: Method
    seed: int
    robots: int
    chunk: int
    backend: Literal["numpy", "numba"]

    @property
    def chunks(self) -> int:
        """How many chunks of ``chunk`` robots the run takes."""
        return math.ceil(self.robots / self.chunk)


def experiment(
    robot,
    wheel_velocities,
    dt,
    robots,
    *,
    wheel_noise=NO_NOISE,
    geometry_sigma=(0.0, 0.0, 0.0),
    initial_pose=None,
    method="exact",
    seed=None,
    chunk=CHUNK,
    backend="auto",
) -> Experiment:
    """The experiment of ``monte_carlo``'s arguments, checked."""
    if not isinstance(robot, DiffDrive):
        raise TypeError(f"robot must be a DiffDrive, got {type(robot).__name__}")
    check_method(method)
    wheels = components(np, wheel_velocities, "wheel_velocities", WHEELS).astype(np.float64)
    if wheels.ndim != 2:
        raise ValueError(f"wheel_velocities must be one history (T, 2), got {wheels.shape}")
    if not np.all(np.isfinite(wheels)):
        raise ValueError("wheel_velocities must be finite")
    step = finite("dt", dt)
    if step <= 0:
        raise ValueError(f"dt must be > 0, got {dt!r}")
    k = WheelNoise.coerce(wheel_noise).k
    sigma = np.asarray(geometry_sigma, dtype=float)
    if sigma.shape != (3,) or not np.all(np.isfinite(sigma)) or np.any(sigma < 0):
        raise ValueError(
            "geometry_sigma (3 relative deviations: left radius, right radius, track) must be "
            "finite and >= 0"
        )
    start = np.zeros(3) if initial_pose is None else initial_pose
    start = components(np, start, "initial_pose", POSE).astype(np.float64)
    if start.shape != (3,) or not np.all(np.isfinite(start)):
        raise ValueError(f"initial_pose must be 3 finite numbers, got {initial_pose!r}")
    if seed is None:
        seed = np.random.SeedSequence().entropy
    seed = _seed(seed)
    robots, chunk = whole("robots", robots, smallest=1), whole("chunk", chunk, smallest=1)
    with np.errstate(over="ignore"):  # refused below, not warned about
        travel = wheels * step
        arcs = np.sum(np.abs(travel), axis=0) * np.array(geometry_of(robot)[:2])
    if not (np.all(np.isfinite(travel)) and np.all(np.isfinite(arcs))):
        raise ValueError(
            "the wheels' travel (wheel_velocities times dt, summed over the history) overflows "
            "the floats: no pose could be computed"
        )
    return Experiment(
        robot, travel, start, k, sigma, method, seed, robots, chunk, _backend(backend)
    )


def _seed(seed: object) -> int:
    """``seed`` as an int >= 0, exactly: an int stays itself (2**53 + 1 is not 2**53), a
    whole float becomes one."""
    if isinstance(seed, int | np.integer) and not isinstance(seed, bool):
        if seed < 0:
            raise ValueError(f"seed must be a whole number from 0, got {seed!r}")
        return int(seed)
    return whole("seed", seed)


def checked_result(final: np.ndarray, moments: Moments) -> MonteCarlo:
    """The result, refused by name where a pose or moment overflowed (NaN poses before)."""
    if not (
        np.all(np.isfinite(final))
        and np.all(np.isfinite(moments.mean))
        and np.all(np.isfinite(moments.m2))
    ):
        raise ValueError(
            "the robots' poses overflow the floats (wheel travel, noise or geometry spread "
            "too large): no finite result"
        )
    return MonteCarlo(final, moments)


def _backend(backend: str) -> Literal["numpy", "numba"]:
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {', '.join(BACKENDS)}, got {backend!r}")
    installed = importlib.util.find_spec("numba") is not None
    if backend == "numba" and not installed:
        raise ImportError("backend='numba' needs numba: pip install 'diffdrive[fast]'")
    return "numba" if backend == "numba" or (backend == "auto" and installed) else "numpy"


def _run_chunk(setup: Experiment, index: int) -> tuple[np.ndarray, Moments]:
    """Final poses and per-step moments of chunk ``index``'s robots (an overflow gives
    non-finite values, which ``checked_result`` refuses, not warnings)."""
    with np.errstate(over="ignore", invalid="ignore"):
        return _chunk_of(setup, index)


def _chunk_of(setup: Experiment, index: int) -> tuple[np.ndarray, Moments]:
    # The same stream as child ``index`` of SeedSequence(seed).spawn(...), without the others.
    sequence = np.random.SeedSequence(setup.seed, spawn_key=(index,))
    count = min(setup.chunk, setup.robots - index * setup.chunk)
    robot = setup.robot
    if setup.backend == "numba":
        from diffdrive.backends.numba_montecarlo import run_chunk

        geometry = np.array(geometry_of(robot))
        final, mean, m2 = run_chunk(
            setup.travel,
            setup.start,
            setup.k,
            setup.geometry_sigma,
            geometry,
            setup.method,
            np.random.default_rng(sequence),
            count,
        )
        return final, Moments(count, mean, m2)
    rng = np.random.default_rng(sequence)
    nominal = np.array(geometry_of(robot))
    drawn = draw_geometry(nominal[:3], setup.geometry_sigma, count, rng)
    geometry = np.column_stack([drawn, np.full(count, nominal[3])])  # (count, 4)
    radii = geometry[:, None, :2]
    steps = len(setup.travel)
    block = max(1, _BLOCK_ELEMENTS // count)
    pose = np.broadcast_to(setup.start, (count, 3)).copy()
    first = Moments(count, pose.mean(axis=0)[None], np.zeros((1, 3, 3)))
    means, m2s = [first.mean], [first.m2]
    for k0 in range(0, steps, block):
        angles = setup.travel[k0 : k0 + block]  # (B, 2) rad, the same for every robot
        if np.any(setup.k):  # noise on each wheel's travel (m), as an angle: (count, B, 2)
            angles = noisy_angles(angles, radii, setup.k, rng)
        increments = twists(geometry, angles)  # (count, B, 3): the step's wheel-to-body map
        poses = accumulate(increments, pose, setup.method)[:, 1:]  # (count, B, 3)
        mean = poses.mean(axis=0)
        deviation = poses - mean
        means.append(mean)
        m2s.append(np.einsum("nti,ntj->tij", deviation, deviation))
        pose = poses[:, -1]
    return pose, Moments(count, np.concatenate(means), np.concatenate(m2s))


def run_chunks(setup: Experiment, indices: range, threads: int = 1) -> tuple[np.ndarray, Moments]:
    """Chunks ``indices`` on ``threads`` threads: their final poses, in chunk order, and
    their merged moments."""
    with ThreadPoolExecutor(max_workers=whole("threads", threads, smallest=1)) as pool:
        finals, parts = zip(*pool.map(lambda i: _run_chunk(setup, i), indices), strict=True)
    return np.concatenate(finals), Moments.combine(parts)


def noisy_angles(angles, radii, k, rng: np.random.Generator) -> np.ndarray:
    """Wheel-angle increments ``angles`` (rad) with each wheel's travel drawn noisy, of
    variance ``k |radius angle|`` (``Odometry``'s model; ``k`` and ``radii`` per wheel, m)."""
    return angles + draw_travel(radii * angles, k, rng) / radii


def monte_carlo(
    robot: DiffDrive,
    wheel_velocities: object,
    dt: float,
    robots: int,
    *,
    wheel_noise: WheelNoiseLike = NO_NOISE,
    geometry_sigma: object = (0.0, 0.0, 0.0),
    initial_pose: object = None,
    method: Method = "exact",
    seed: int | None = None,
    chunk: int = CHUNK,
    backend: Backend = "auto",
    threads: int = 1,
) -> MonteCarlo:
    """``robots`` noisy copies of ``robot`` driving ``wheel_velocities`` ``(T, 2)`` (rad/s),
    each held for ``dt`` s, from ``initial_pose``; see the module for the errors, the seeding
    and the backends. Returns the final poses and the per-step mean and covariance."""
    setup = experiment(
        robot,
        wheel_velocities,
        dt,
        robots,
        wheel_noise=wheel_noise,
        geometry_sigma=geometry_sigma,
        initial_pose=initial_pose,
        method=method,
        seed=seed,
        chunk=chunk,
        backend=backend,
    )
    final, moments = run_chunks(setup, range(setup.chunks), threads)
    return checked_result(final, moments)
