"""Beyond one machine: Monte Carlo and many logs on a Dask cluster (extra ``diffdrive[dask]``).

``monte_carlo`` shares the chunks of ``diffdrive.montecarlo.monte_carlo`` out among Dask tasks,
each of which reduces its robots on its worker: what travels back is each robot's final pose
and each task's per-step mean and sums of squared deviations, never a robot's path. The
statistics merge to those of one process, to rounding (the chunks draw the same numbers
wherever they run). ``map_runs`` runs one task per item (a log to calibrate or to evaluate).

Without a ``client``, both start a ``LocalCluster`` of one single-threaded worker process per
core for the call. Tasks set the compiled kernels (numba's and simulate's) to one thread, so
that workers do not oversubscribe the cores. On a cluster, pass its client; the calls are the same:

    from dask_jobqueue import SLURMCluster            # or dask_kubernetes' KubeCluster
    from distributed import Client
    cluster = SLURMCluster(cores=1, memory="4GB", processes=1)
    cluster.scale(jobs=64)
    with Client(cluster) as client:
        result = monte_carlo(robot, wheels, 0.01, 10**7, wheel_noise=1e-4, client=client)
"""

from __future__ import annotations

import importlib.util
import itertools
import os
import sys
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np

from diffdrive._validate import whole
from diffdrive.model import DiffDrive
from diffdrive.montecarlo import (
    Experiment,
    Moments,
    MonteCarlo,
    checked_result,
    experiment,
    run_chunks,
)

__all__ = ["map_runs", "monte_carlo"]


def _one_thread() -> None:
    """The compiled kernels' threads to one: the worker processes share out the cores."""
    from diffdrive.backends import simulate_kernel

    simulate_kernel.set_threads(1)
    if importlib.util.find_spec("numba") is not None:
        import numba

        numba.set_num_threads(1)


def _task(setup: Experiment, first: int, stop: int) -> tuple[np.ndarray, Moments]:
    """Chunks ``first:stop`` of a Monte Carlo, reduced on the worker."""
    _one_thread()
    return run_chunks(setup, range(first, stop))


def _call(function: Callable[[Any], Any], item: Any) -> Any:
    _one_thread()
    return function(item)


@contextmanager
def _client(client: Any) -> Iterator[Any]:
    """The given client, or one on a LocalCluster made (and closed) for the call."""
    if client is not None:
        yield client
        return
    from distributed import Client, LocalCluster

    if getattr(sys.modules.get("__main__"), "__name__", "") == "__mp_main__":
        # A worker process importing the user's script again: the script has no main guard.
        raise RuntimeError(_GUARD)
    workers = os.cpu_count() or 1
    try:
        # ":0", a free port: None means Dask's fixed 8787, which a second cluster on the
        # machine finds taken.
        cluster = LocalCluster(
            n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0"
        )
    except RuntimeError:
        raise RuntimeError(_GUARD) from None
    with cluster, Client(cluster) as local:
        yield local


_GUARD = (
    "the local Dask workers could not start. A script that calls diffdrive.distributed "
    'without a client must do so under `if __name__ == "__main__":` (each worker process '
    "imports the script again, and would start a cluster of its own); or pass client= a "
    "dask.distributed Client"
)


def _threads(client: Any) -> int:
    return max(1, sum(client.nthreads().values()))


def monte_carlo(
    robot: DiffDrive,
    wheel_velocities: object,
    dt: float,
    robots: int,
    *,
    client: Any = None,
    tasks: int | None = None,
    **options: Any,
) -> MonteCarlo:
    """``diffdrive.montecarlo.monte_carlo`` over Dask tasks (default: one per worker thread),
    each reducing a contiguous run of chunks; ``options`` are that function's (``wheel_noise``,
    ``geometry_sigma``, ``seed``, ``chunk``, ``backend``, ...). Give ``seed`` for results
    that can be repeated."""
    setup = experiment(robot, wheel_velocities, dt, robots, **options)
    if tasks is not None:
        tasks = whole("tasks", tasks, smallest=1)
    with _client(client) as active:
        count = min(setup.chunks, tasks or _threads(active))
        bounds = np.linspace(0, setup.chunks, count + 1).round().astype(int)
        # Not hashed: a second call with the same plan would share the first one's key,
        # which the first call releases (lost dependencies).
        shared = active.scatter(setup, broadcast=True, hash=False)
        futures = [
            active.submit(_task, shared, int(a), int(b), pure=False)
            for a, b in itertools.pairwise(bounds)
        ]
        results = active.gather(futures)
    finals, parts = zip(*results, strict=True)
    return checked_result(np.concatenate(finals), Moments.combine(parts))


def map_runs(function: Callable[[Any], Any], items: Iterable[Any], *, client: Any = None) -> list:
    """``[function(item) for item in items]``, one Dask task per item, in order.

    ``function`` must be importable by the workers (a module's function, or a
    ``functools.partial`` of one): e.g. a calibration or an evaluation of one log file.
    """
    items = list(items)
    with _client(client) as active:
        return active.gather(active.map(_call, [function] * len(items), items, pure=False))
