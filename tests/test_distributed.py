"""diffdrive.distributed on a LocalCluster of two worker processes: the same statistics as
one process, no pose array larger than a task's, and one task per log."""

import functools

import numpy as np
import pytest

import diffdrive as dd
from diffdrive import distributed
from diffdrive.calibration import calibrate
from diffdrive.montecarlo import experiment, monte_carlo
from diffdrive.simulation import dead_reckon

pytestmark = pytest.mark.slow


@pytest.fixture(autouse=True, scope="module")
def _dask():
    """Imported here, not at collection (0.3 s)."""
    pytest.importorskip("distributed", reason="dask distributed is part of the test extra")


ROBOT = dd.DiffDrive(0.05, 0.3)
DT = 0.02
T = np.arange(300) * DT
WHEELS = np.stack([8 + 3 * np.sin(T), 8 - 3 * np.sin(0.7 * T)], axis=-1)


@pytest.fixture(scope="module")
def client():
    from distributed import Client, LocalCluster

    with (
        LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0"
        ) as cluster,
        Client(cluster) as connected,
    ):
        yield connected


def test_monte_carlo_on_two_workers_equals_one_process(client):
    options = {
        "wheel_noise": (1e-4, 2e-4),
        "geometry_sigma": (0.005, 0.005, 0.01),
        "seed": 7,
        "chunk": 500,
    }
    local = monte_carlo(ROBOT, WHEELS, DT, 3000, **options)
    spread = distributed.monte_carlo(ROBOT, WHEELS, DT, 3000, client=client, tasks=4, **options)
    np.testing.assert_array_equal(spread.final, local.final)  # the same numbers drawn
    np.testing.assert_allclose(spread.mean, local.mean, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(spread.covariance, local.covariance, rtol=1e-9, atol=1e-18)


def test_a_task_sends_back_statistics_not_paths():
    setup = experiment(ROBOT, WHEELS, DT, 3000, wheel_noise=(1e-4, 0.0), seed=1, chunk=500)
    final, moments = distributed._task(setup, 0, 3)  # three chunks, as a worker runs them
    assert final.shape == (1500, 3)  # one pose per robot
    assert moments.mean.shape == (301, 3)
    assert moments.m2.shape == (301, 3, 3)  # per step, over the robots: never robots x steps


def _run(seed: int):
    rng = np.random.default_rng(seed)
    wheels = np.tile([0.08, 0.16], (400, 1)) * np.where(np.arange(400) < 200, 1, -1)[:, None]
    wheels = wheels + rng.normal(0, 0.01, wheels.shape)
    true = dd.DiffDrive(left_wheel_radius=0.0497, right_wheel_radius=0.0503, track_width=0.31)
    return wheels, dead_reckon(true, wheels, np.zeros(3))


def _calibrate(seeds):
    result = calibrate(ROBOT, [_run(seed) for seed in seeds], "least_squares")
    return result.robot.track_width


def test_map_runs_gives_one_answer_per_item_in_order(client):
    items = [(1, 2), (3, 4), (5, 6)]
    assert distributed.map_runs(_calibrate, items, client=client) == [
        _calibrate(seeds) for seeds in items
    ]
    scaled = distributed.map_runs(functools.partial(np.multiply, 2.0), [1.0, 2.0], client=client)
    assert scaled == [2.0, 4.0]


def test_the_same_experiment_twice_on_one_client(client):
    """The second call lost its scattered plan to the first one's release before."""
    first, second = (
        distributed.monte_carlo(
            ROBOT, WHEELS, DT, 200, seed=3, client=client, wheel_noise=(1e-4, 0.0)
        )
        for _ in range(2)
    )
    np.testing.assert_array_equal(first.final, second.final)
    with pytest.raises(ValueError, match="tasks must be a whole number from 1"):
        distributed.monte_carlo(ROBOT, WHEELS, DT, 10, seed=3, client=client, tasks=0)


def test_a_script_without_a_main_guard_is_told_what_to_do(tmp_path):
    """Without a client, a plain script's workers import it again: it failed with screens of
    "Nanny failed to start"; the last word is now what to do."""
    import subprocess
    import sys

    script = tmp_path / "plain.py"
    script.write_text(
        "import numpy as np\n"
        "import diffdrive as dd\n"
        "from diffdrive import distributed\n"
        "distributed.monte_carlo(dd.DiffDrive(0.05, 0.3), np.ones((10, 2)), 0.1, 100, seed=1)\n"
    )
    done = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=120, cwd=tmp_path
    )
    assert done.returncode != 0
    last = done.stderr.strip().splitlines()[-1]
    assert 'under `if __name__ == "__main__":`' in last
    assert "or pass client=" in last
