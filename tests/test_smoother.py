"""estimate_trajectory's whole-log pass (``smoother``): the C core held to its Python twin
interval by interval, filter and smoother; the whole-log filter held to the streaming
estimator fed the same log; the pipeline (episodes included) the same on both cores."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import diffdrive as dd
from diffdrive.estimation import (
    Encoders,
    EstimatorSettings,
    FixOffset,
    Gate,
    Gyro,
    GyroNoise,
    Measurement,
    Prior,
    WholeLog,
    Window,
    estimate_trajectory,
    fusion,
    measurements_of,
)
from diffdrive.estimation import smoother as whole

ROBOT = dd.SkidSteer(0.1, 0.45, -0.35, icr_x=0.03)  # an axle offset and a reference offset
WHEELS = EstimatorSettings("wheels")
needs_c = pytest.mark.skipif(not fusion.COMPILED, reason="the C core was not built")

# one interval: left and right increments (rad), dt (s), the gyro's turn (rad), forced
intervals = st.tuples(
    st.floats(-0.5, 0.5), st.floats(-0.5, 0.5), st.floats(1e-3, 0.05), st.floats(-0.05, 0.05),
    st.booleans(),
)  # fmt: skip
# one measurement: kind, where in the log (0: its start, 1: its end), values, lever arm
sightings = st.tuples(
    st.sampled_from(["pose", "position", "heading"]),
    st.one_of(st.just(0.0), st.just(1.0), st.floats(0.0, 1.0)),
    st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(-0.5, 0.5)),
    st.tuples(st.floats(-0.3, 0.3), st.floats(-0.3, 0.3)),
)


def make_log(steps, seen):
    times = np.concatenate([[0.0], np.cumsum([dt for _, _, dt, _, _ in steps])])
    increments = np.array([(left, right) for left, right, _, _, _ in steps])
    turns = np.array([g for _, _, _, g, _ in steps])
    forced = np.array([f for *_, f in steps])
    made = []
    for kind, where, value, arm in seen:
        stamp = float(times[-1] * where)
        size = {"pose": 3, "position": 2, "heading": 1}[kind]
        sigma = (0.3, 0.2, 0.1)[:size]
        made.append(Measurement.make(kind, stamp, value[:size], sigma, arm if size > 1 else None))
    return times, increments, turns, forced, sorted(made, key=lambda m: m.order)


# the states beyond the pose, bias and turn scale: the distance scale, the fixes' offset
EXTRA_STATES = (
    {},
    {"distance_scale": Prior(0.97, 0.05)},
    {"fix_offset": FixOffset(rate=0.2)},
    {"fix_offset": FixOffset(0.1, 0.3), "distance_scale": Prior(sigma=0.05)},
)


def log_settings(heading, scale, **extra):
    """The settings the tests here run: a whole log's window, the gyro's noise and the
    wheels' given (with a counter's rounding, 1,000 counts a turn), the turn scale estimated if
    ``scale``, and ``extra``."""
    return EstimatorSettings(
        heading, wheel_noise=(1e-4, 2e-4), gyro_noise=GyroNoise(2e-2, 1e-3, 5e-2),
        turn_scale=Prior(sigma=0.1 if scale else 0.0), window=Window(np.inf, 0.0),
        encoders=Encoders(ticks_per_revolution=1000), **extra,
    )  # fmt: skip


def run_core(kind, heading, scale, log, smooth, extra=None, spread=True):
    """``log`` through a core's whole-log pass; with ``spread``, a gyro whose samples leave
    each turn open by a variance that varies with it (a stream given angles has none)."""
    times, increments, turns, forced, ordered = log
    estimator = kind(
        ROBOT, log_settings(heading, scale, **(extra or {})), initial_pose=(0.1, -0.2, 0.3),
        initial_covariance=np.eye(3) * 1e-3, initial_time=0.0,
    )  # fmt: skip
    log_of = whole._Log(
        times, increments, turns if heading != "wheels" else np.full(len(turns), np.nan),
        0.1 * turns**2 * spread, np.zeros(len(turns), dtype=bool), whole._packed(ordered),
    )  # fmt: skip
    return whole._run(estimator, log_of, smooth, forced, records=True)


@pytest.mark.slow
@needs_c
@settings(max_examples=60, deadline=None)
@given(
    st.lists(intervals, min_size=1, max_size=40),
    st.lists(sightings, max_size=8),
    st.sampled_from(["wheels", "gyro", "fused"]),
    st.booleans(),
    st.booleans(),
    st.sampled_from(EXTRA_STATES),
    st.sampled_from(["refuse", "inflate"]),
)
def test_the_c_whole_log_pass_is_its_python_twin(
    steps, seen, heading, scale, smooth, extra, outliers
):
    """Any log, forced intervals and measurements of every kind (at the start, at interval
    ends, inside intervals, several at one stamp), with or without the distance scale and
    the fixes' offset as states, outliers refused or inflated past a narrow gate: the C pass
    and the Python one give the same state and covariance at every row, filtered and
    smoothed, the same slip flags and scores, and the same outcomes and likelihood terms;
    smoothed, the same record of every step, which run back through the RTS step gives the
    smoothed states."""
    log = make_log(steps, seen)
    extra = dict(extra, gate=Gate(0.9, outliers))
    c_run = run_core(fusion.PoseEstimator, heading, scale, log, smooth, extra)
    python_run = run_core(fusion._PythonPoseEstimator, heading, scale, log, smooth, extra)
    c, python = c_run.out, python_run.out
    if smooth:
        assert c_run.records is not None
        assert python_run.records is not None
        _same_records(c_run.records, python_run.records)
        _records_smooth_to(c_run.records, c.states, c.covariances)
    else:
        assert c_run.records is None
    np.testing.assert_allclose(c.states, python.states, rtol=1e-9, atol=1e-11)
    scale_of = np.maximum(np.abs(python.covariances).max(axis=(1, 2)), 1e-12)[:, None, None]
    np.testing.assert_allclose(c.covariances / scale_of, python.covariances / scale_of, atol=1e-8)
    np.testing.assert_array_equal(c.slips, python.slips)
    np.testing.assert_allclose(c.scores, python.scores, rtol=1e-7, atol=1e-9)
    np.testing.assert_array_equal(c.accepted, python.accepted)
    np.testing.assert_allclose(c.distances, python.distances, rtol=1e-7, atol=1e-9)
    np.testing.assert_allclose(c.log_dets, python.log_dets, rtol=1e-7, atol=1e-9)


def _same_records(c, python):
    np.testing.assert_array_equal(c.interval, python.interval)
    for name in ("before", "after", "gain"):
        np.testing.assert_allclose(
            getattr(c, name), getattr(python, name), rtol=1e-9, atol=1e-10, err_msg=name
        )
    for name in ("before_covariance", "after_covariance"):
        got, want = getattr(c, name), getattr(python, name)
        scale = np.maximum(np.abs(want).max(axis=(1, 2)), 1e-12)[:, None, None]
        np.testing.assert_allclose(got / scale, want / scale, atol=1e-8, err_msg=name)


def _records_smooth_to(records, states, covariances):
    """The RTS pass written out from the records alone, from the last row back: each step's
    smoothed start from its smoothed end; a row's state is that of its interval's first step."""
    x, P = states[-1], covariances[-1]
    for s in range(len(records.interval) - 1, -1, -1):
        C = records.gain[s]
        x = records.before[s] + C @ (x - records.after[s])
        P = records.before_covariance[s] + C @ (P - records.after_covariance[s]) @ C.T
        P = 0.5 * (P + P.T)
        if s == 0 or records.interval[s - 1] != records.interval[s]:
            row = records.interval[s] - 1
            np.testing.assert_allclose(x, states[row], rtol=1e-9, atol=1e-10)
            scale = max(np.abs(covariances[row]).max(), 1e-12)
            np.testing.assert_allclose(P / scale, covariances[row] / scale, atol=1e-8)


@settings(max_examples=30, deadline=None)
@given(st.lists(intervals, min_size=1, max_size=40), st.lists(sightings, max_size=6))
def test_the_whole_log_filter_is_the_streaming_estimator(steps, seen):
    """The whole-log filter on a log is the streaming PoseEstimator fed the same readings,
    each measurement given as soon as the wheels reach its stamp."""
    log = make_log(steps, seen)
    times, increments, turns, _, ordered = log
    unforced = (*log[:3], np.zeros(len(turns), dtype=bool), ordered)
    run = run_core(fusion.PoseEstimator, "fused", True, unforced, False, spread=False).out
    streaming = fusion.PoseEstimator(
        ROBOT, log_settings("fused", True), initial_pose=(0.1, -0.2, 0.3),
        initial_covariance=np.eye(3) * 1e-3, initial_time=0.0,
    )  # fmt: skip
    given_ = 0
    while given_ < len(ordered) and ordered[given_].t == 0.0:
        streaming.add(ordered[given_])
        given_ += 1
    for k in range(1, len(times)):
        streaming.update_increments(*increments[k - 1], times[k], gyro_angle=turns[k - 1])
        while given_ < len(ordered) and ordered[given_].t <= times[k]:
            streaming.add(ordered[given_])
            given_ += 1
        np.testing.assert_allclose(run.states[k], streaming.state, rtol=1e-9, atol=1e-11)
        assert run.slips[k] == streaming.slip
    assert int(run.accepted.sum()) == streaming.accepted


@pytest.mark.slow
@needs_c
def test_the_pipeline_is_the_same_on_both_cores(monkeypatch):
    """A log with a slip episode the per-interval test misses, GPS-like fixes and the
    smoother: estimate_trajectory on the C core and on the Python one agree row by row."""
    rng = np.random.default_rng(3)
    robot = dd.DiffDrive(wheel_radius=0.1, track_width=0.5)
    times = np.arange(0.0, 20.0 + 1e-9, 0.02)
    t = times[:-1]
    wheels = np.column_stack([8.0 + 2.0 * np.cos(t / 2.3), 8.0 + 2.0 * np.sin(t / 3)])
    truth = dd.simulate(robot, wheels, times=times).poses
    increments = wheels * 0.02 + rng.normal(size=wheels.shape) * 3e-3
    increments[300:340, 0] *= 1.3  # the left wheel spins a third again as far as it rolls
    rate = np.gradient(np.unwrap(truth[:, 2]), times) + 0.01 + rng.normal(size=len(times)) * 0.01
    fixes = truth[::50, :2] + rng.normal(size=(len(times[::50]), 2)) * 0.2
    measurements = measurements_of("position", times[::50], fixes, 0.2)
    results = []
    for core in (fusion.PoseEstimator, fusion._PythonPoseEstimator):
        monkeypatch.setattr(whole, "PoseEstimator", core)
        results.append(
            estimate_trajectory(
                robot,
                times,
                increments,
                gyro=Gyro(times, rate),
                measurements=measurements,
                settings=EstimatorSettings(wheel_noise=1e-4),
            )
        )
    c, python = results
    assert np.any(c.slip[300:341])
    np.testing.assert_array_equal(c.slip, python.slip)
    np.testing.assert_allclose(c.poses, python.poses, rtol=0, atol=1e-8)
    np.testing.assert_allclose(c.covariances, python.covariances, rtol=1e-6, atol=1e-14)
    np.testing.assert_allclose(c.twists, python.twists, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(c.accepted, python.accepted)


def test_strided_and_integer_arrays_are_a_log_like_any_other():
    """Every other row of a longer log (views, not copies) and integer increments: the same
    estimate as the same numbers in fresh float arrays."""
    times = np.arange(40) * 0.05
    increments = np.tile([3, 4], (39, 1))  # rad, integers
    rate = np.full(40, 0.2)
    strided = estimate_trajectory(
        ROBOT, times[::2], increments[::2][:19], gyro=Gyro(times[::2], rate[::2])
    )
    fresh = estimate_trajectory(
        ROBOT, times[::2].copy(), increments[::2][:19].astype(float),
        gyro=Gyro(times[::2].copy(), rate[::2].copy()),
    )  # fmt: skip
    np.testing.assert_array_equal(strided.poses, fresh.poses)
    np.testing.assert_array_equal(strided.covariances, fresh.covariances)


def test_a_bad_interval_is_named_before_anything_runs():
    times = np.arange(6) * 0.1
    increments = np.ones((5, 2))
    increments[3, 1] = np.nan
    with pytest.raises(ValueError, match=r"interval 3 \(0.3 to 0.4 s\): the wheel increments"):
        estimate_trajectory(ROBOT, times, increments, settings=WHEELS)
    increments[3, 1] = 1.0
    limited = WHEELS.replace(encoders=Encoders(max_wheel_speed=5.0))
    with pytest.raises(ValueError, match=r"interval 0 .*over max_wheel_speed 5.0 rad/s"):
        estimate_trajectory(ROBOT, times, increments, settings=limited)
    huge = np.full((5, 2), 1e307)  # 1e308 rad/s: finite, but the covariance overflows
    with pytest.raises(ValueError, match=r"interval 0 \(0 to 0.1 s\): the update would overflow"):
        estimate_trajectory(ROBOT, times, huge, settings=WHEELS)


def test_each_core_is_built_from_one_settings_value_that_names_what_is_wrong():
    """The C cores and their twins take the same settings object (CoreSettings for the
    estimator, OdometrySettings for odometry), read by name; a bad one is refused naming the
    field, and both cores built from one value start in the same state."""
    import dataclasses

    from diffdrive.backends import _odometry
    from diffdrive.estimation._estimator_python import EstimatorCore as PythonEstimatorCore
    from diffdrive.estimation._odometry_python import OdometryCore as PythonOdometryCore

    estimator = fusion.PoseEstimator(
        ROBOT, EstimatorSettings(wheel_noise=(1e-4, 2e-4)), initial_pose=(1.0, 2.0, 0.3)
    )
    odometry_settings, settings = estimator._wheels.settings, estimator.config
    assert settings.k == (1e-4, 2e-4)
    assert settings.gates[0] == pytest.approx(10.828, abs=1e-3)  # chi-square, 1 dof, 0.999
    wheels, twin_wheels = (
        _odometry.OdometryCore(odometry_settings),
        PythonOdometryCore(odometry_settings),
    )
    c_core = _odometry.EstimatorCore(wheels, settings)
    twin = PythonEstimatorCore(twin_wheels, settings)
    np.testing.assert_array_equal(c_core._state_now(), twin._state_now())
    with pytest.raises(ValueError, match="state must have 8 numbers"):
        _odometry.EstimatorCore(wheels, dataclasses.replace(settings, state=(0.0, 1.0)))
    with pytest.raises(AttributeError, match="no attribute 'wheel_floor'"):
        _odometry.EstimatorCore(wheels, odometry_settings)
    with pytest.raises(ValueError, match="drive must have 4 numbers"):
        _odometry.OdometryCore(dataclasses.replace(odometry_settings, drive=(0.05, 0.3)))


def test_estimate_trajectory_keeps_the_records_only_when_asked_and_smoothing():
    times = np.arange(0.0, 2.0 + 1e-9, 0.1)
    increments = np.full((len(times) - 1, 2), [0.5, 0.6])
    fixes = measurements_of("position", [0.55, 1.0, 1.05], np.zeros((3, 2)), 0.5)
    records = WHEELS.replace(whole_log=WholeLog(records=True))
    kept = estimate_trajectory(ROBOT, times, increments, measurements=fixes, settings=records)
    assert kept.records is not None
    # 20 intervals, the ones holding 0.55 and 1.05 cut in two (1.0 ends an interval)
    assert len(kept.records.interval) == 22
    assert kept.records.gain.shape == (22, 8, 8)
    plain = estimate_trajectory(ROBOT, times, increments, measurements=fixes, settings=WHEELS)
    assert plain.records is None
    with pytest.raises(ValueError, match="records are the smoother's"):
        estimate_trajectory(
            ROBOT, times, increments, measurements=fixes, smooth=False, settings=records
        )
