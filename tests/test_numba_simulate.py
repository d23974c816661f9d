"""The numba kernel: equal to the NumPy path, its own pieces, its cache of machine code, and how
simulate chooses it."""

import importlib.util
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import diffdrive as dd
from diffdrive import integrate, simulation
from diffdrive.backends import simulate_kernel
from strategies import geometry


def _compiled():
    """The numba kernel's module, imported at use rather than at collection."""
    from diffdrive.backends import numba_simulate

    return numba_simulate


ROBOT = dd.DiffDrive(wheel_radius=0.05, track_width=0.3)
# Robot-steps from which "auto" takes the kernel once it is loaded (2^17: past its call cost).
LOADED_THRESHOLD = 1 << 17


def both(*args, **kwargs):
    """The trajectories from the NumPy path and from the numba kernel."""
    return tuple(dd.simulate(*args, **kwargs, backend=b) for b in ("numpy", "numba"))


def assert_same_trajectory(numpy_path, compiled):
    # Each is float64 to about 1e-14 of the path length; 1e-9 leaves room and catches any slip.
    scale = 1.0 + float(np.max(numpy_path.distance))
    np.testing.assert_allclose(compiled.poses, numpy_path.poses, rtol=0, atol=1e-9 * scale)
    np.testing.assert_array_equal(compiled.times, numpy_path.times)
    np.testing.assert_array_equal(compiled.wheel_velocities, numpy_path.wheel_velocities)


histories = st.sampled_from(["velocities", "irregular times", "positions", "function"])


@pytest.mark.slow
@given(
    geometry(),
    st.sampled_from(integrate.METHODS),
    histories,
    st.sampled_from([(), (3,), (2, 2)]),
    st.integers(1, 300),
    st.sampled_from([0.001, 0.05]),
    st.integers(0, 2**32 - 1),
)
@settings(max_examples=60, deadline=None)
def test_kernel_equals_the_numpy_path(params, method, history, robots, steps, dt, seed):
    robot = dd.DiffDrive(**params)
    rng = np.random.default_rng(seed)
    # Up to 60 rad/s at 0.05 s turns by more than 1/8 rad a step: both sides of the Taylor
    # switch. Up to 300 steps crosses several re-anchorings of the heading's cos and sin.
    wheels = rng.uniform(-60.0, 60.0, (*robots, steps, 2))
    start = rng.uniform(-3.0, 3.0, (*robots, 3))
    common = {"initial_pose": start, "method": method}
    if history == "velocities":
        numpy_path, compiled = both(robot, wheels, dt=dt, **common)
    elif history == "irregular times":
        times = np.cumsum(rng.uniform(0.1, 1.0, steps + 1)) * dt
        numpy_path, compiled = both(robot, wheels, times=times, **common)
    elif history == "positions":
        angles = np.cumsum(rng.uniform(-3.0, 3.0, (*robots, steps + 1, 2)), axis=-2)
        numpy_path, compiled = both(robot, wheel_positions=angles, dt=dt, **common)
    else:
        numpy_path, compiled = both(
            robot,
            lambda t: np.stack([np.sin(t), np.cos(3 * t)], -1),
            dt=dt,
            duration=steps * dt,
            **common,
        )
    assert_same_trajectory(numpy_path, compiled)


@pytest.mark.parametrize("chunks", [2, 3, 7])
@pytest.mark.parametrize("method", integrate.METHODS)
def test_chunked_passes_equal_one_pass(chunks, method):
    """The three-pass split of one robot's steps, whatever the number of threads here."""
    wheels = np.random.default_rng(4).uniform(-30.0, 30.0, (2, 1001, 2))
    times = np.linspace(0.0, 10.0, 1002)[None]
    start = np.array([[1.0, -2.0, 3.0], [0.0, 0.5, -1.0]])
    robot = dd.DiffDrive(
        left_wheel_radius=0.05, right_wheel_radius=0.06, track_width=0.3, axle_offset=0.1
    )
    one, split = np.empty((2, 1002, 3)), np.empty((2, 1002, 3))
    simulate_kernel.integrate_history(robot, wheels, times, False, start, method, one, chunks=1)
    simulate_kernel.integrate_history(robot, wheels, times, False, start, method, split, chunks)
    np.testing.assert_allclose(split, one, rtol=0, atol=1e-12)


def test_every_method_has_its_flags():
    """One decoding of a method into its flags serves every backend (the kernel's own table
    is gone); the C core takes the method by its index in the same order."""
    from diffdrive import _step

    assert tuple(_step.METHOD_FLAGS) == integrate.METHODS
    assert [_step.method_flags(method) for method in integrate.METHODS] == [
        (0.0, False),
        (0.5, False),
        (0.5, True),
    ]
    with pytest.raises(ValueError, match="method must be one of euler, rk2, exact"):
        _step.method_flags("midpoint")


def test_chunks_use_the_threads_only_where_they_pay():
    threads, chunk_count = 4, simulate_kernel.chunk_count
    assert chunk_count(1, 10**7, np.float64, threads) == 4
    assert chunk_count(3, 10**7, np.float64, threads) == 2
    assert chunk_count(1000, 10**4, np.float64, threads) == 1
    assert chunk_count(1, 100, np.float64, threads) == 1  # too short to split
    assert chunk_count(1, 10**7, np.float32, threads) == 1  # keeps the half ulp


def test_taylor_forms_are_within_an_ulp_of_libm():
    for u in np.concatenate([np.geomspace(1e-12, 1 / 16, 2000), -np.geomspace(1e-9, 0.06, 50)]):
        sinc, cosine = _compiled()._sinc_cos(u)
        assert abs(sinc - math.sin(u) / u) <= 2 * math.ulp(1.0), u
        assert abs(cosine - math.cos(u)) <= 2 * math.ulp(1.0), u
    assert _compiled()._sinc_cos(0.0) == (1.0, 1.0)


def test_a_million_steps_on_a_circle_end_on_the_circle():
    """Compensated block sums and the turned cos and sin: 10^6 steps, 750 rad, 1e-11 m."""
    radius, speed, steps, dt = 2.0, 1.5, 1_000_000, 1e-3
    wheels = ROBOT.to_wheel_velocities(dd.Twist(speed, 0.0, speed / radius)).to_array()
    trajectory = dd.simulate(ROBOT, np.tile(wheels, (steps, 1)), dt=dt, backend="numba")
    angle = speed / radius * steps * dt
    expected = [radius * math.sin(angle), radius * (1 - math.cos(angle)), angle]
    np.testing.assert_allclose(trajectory.final_pose, expected, rtol=0, atol=1e-11)


def test_auto_uses_the_kernel_for_large_calls_only(monkeypatch):
    calls = []
    original = simulation._integrate_compiled
    monkeypatch.setattr(
        simulation, "_integrate_compiled", lambda *a: calls.append(1) or original(*a)
    )
    dd.simulate(ROBOT, np.ones((100, 2)), dt=0.01)
    assert calls == []
    dd.simulate(ROBOT, np.ones((4, LOADED_THRESHOLD // 4, 2)), dt=0.01)
    assert calls == [1]


def test_auto_weighs_loading_and_compiling_the_kernel(monkeypatch):
    f64 = np.dtype("float64")
    monkeypatch.setattr(simulate_kernel, "loaded", lambda dtype: False)
    monkeypatch.setattr(simulate_kernel, "cached", lambda dtype: True)
    assert not simulation._use_numba("auto", 800_000, f64)  # a load costs 0.15 s: 0.88e6 steps
    assert simulation._use_numba("auto", 1_000_000, f64)
    monkeypatch.setattr(simulate_kernel, "cached", lambda dtype: False)
    assert not simulation._use_numba("auto", 25_000_000, f64)  # a first compile: 5 s
    assert simulation._use_numba("auto", 30_000_000, f64)
    assert not simulation._use_numba("auto", 50_000_000, np.dtype("float16"))


def test_without_numba_auto_falls_back_and_numba_is_refused(monkeypatch):
    real = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util, "find_spec", lambda name, *a: None if name == "numba" else real(name, *a)
    )
    wheels = np.ones((LOADED_THRESHOLD, 2))
    assert dd.simulate(ROBOT, wheels, dt=0.01).poses.shape == (wheels.shape[0] + 1, 3)
    with pytest.raises(ImportError, match=r"diffdrive\[fast\]"):
        dd.simulate(ROBOT, wheels, dt=0.01, backend="numba")


def test_an_unknown_backend_is_refused():
    with pytest.raises(ValueError, match="backend must be one of auto, numpy, numba, got 'c'"):
        dd.simulate(ROBOT, np.ones((3, 2)), dt=0.01, backend="c")


def test_float16_stays_on_the_numpy_path():
    wheels = np.ones((LOADED_THRESHOLD, 2), dtype=np.float16)
    assert dd.simulate(ROBOT, wheels, dt=0.01).poses.dtype == np.float16
    with pytest.raises(ValueError, match="backend='numba' takes float32 or float64 data"):
        dd.simulate(ROBOT, wheels, dt=0.01, backend="numba")


def test_one_sinc_in_every_layer():
    """``_step.sinc`` as written, compiled, over arrays and behind ``se2.sinc``: one rule."""
    from diffdrive import _step, batch, se2

    grid = np.concatenate([np.geomspace(1e-9, 3.0, 400), [_step.TAYLOR_LIMIT, 0.0]])
    for u in np.concatenate([grid, -grid]):
        want = _step.sinc(float(u))
        assert se2.sinc(float(u)) == want
        assert _compiled().STEP["sinc"](float(u)) == want
        assert abs(float(batch.sinc(np.float64(u))) - want) <= math.ulp(1.0), u


@pytest.mark.parametrize(
    ("running", "own", "idle"),
    [(1, 1, 4), (2, 1, 3), (4, 1, 1), (9, 1, 1), (None, 1, 4), (3, 2, 3), (3, 3, 4)],
)
def test_a_robot_is_cut_only_for_the_threads_no_other_task_holds(monkeypatch, running, own, idle):
    """Linux's count of runnable tasks includes this process's own (this thread, and a
    parallel pool's threads spinning after a pass, which are no other task's); where it
    cannot be read, every thread counts as idle."""
    monkeypatch.setattr(simulate_kernel, "_running_tasks", lambda: running)
    monkeypatch.setattr(simulate_kernel, "_own_running", lambda: own)
    assert simulate_kernel.idle_threads(4) == idle


def test_this_process_counts_at_least_its_running_thread():
    assert simulate_kernel._own_running() >= 1
