"""Position fixes that wander: ``estimation.fixes.identify_fixes``, the fixes' offset and the
distance scale as states, outliers inflated past the gate, and the measurements' likelihood."""

from __future__ import annotations

import math

import numpy as np
import pytest

import diffdrive as dd
from diffdrive.estimation import EstimatorSettings as S
from diffdrive.estimation import (
    FixOffset,
    Gate,
    PoseEstimator,
    Prior,
    WholeLog,
    estimate_trajectory,
    measurements_of,
)
from diffdrive.estimation import filter as ekf
from diffdrive.estimation.fixes import identify_fixes
from diffdrive.estimation.fusion import _PythonPoseEstimator
from diffdrive.estimation.measurements import Measurement
from diffdrive.sensors import AbsoluteModel, absolute_readings

ROBOT = dd.DiffDrive(wheel_radius=0.1, track_width=0.5)
WHEELS = S("wheels")
IDENTIFIED = S("wheels", whole_log=WholeLog(fixes="identified"))
RATE = 20.0  # Hz, the wheels
FIX_RATE = 2.0  # Hz, the fixes


def drive(seed: int, duration: float = 300.0, scale: float = 0.97):
    """A mixed drive (straights, arcs both ways, turns on the spot): its stamps, true poses,
    the wheel increments a robot whose wheels over-read the distance travelled by
    ``1 / scale`` (and read the turn right: the distance scale's model) reports, with a
    little noise, and the random stream."""
    rng = np.random.default_rng(seed)
    times = np.arange(0.0, duration, 1.0 / RATE)
    pieces = np.repeat(rng.integers(0, 4, size=len(times) // 100 + 1), 100)[: len(times) - 1]
    speed = np.choose(pieces, [0.8, 0.6, 0.6, 0.0])
    turn = np.choose(pieces, [0.0, 0.4, -0.4, 0.8])
    dt = np.diff(times)
    heading = np.concatenate([[0.3], 0.3 + np.cumsum(turn * dt)])
    middle = heading[:-1] + 0.5 * turn * dt
    steps = np.column_stack([speed * dt * np.cos(middle), speed * dt * np.sin(middle)])
    truth = np.column_stack([np.vstack([[0.0, 0.0], np.cumsum(steps, axis=0)]), heading])
    b, r = ROBOT.track_width / 2, ROBOT.wheel_radius
    left = (speed / scale - turn * b) * dt / r
    right = (speed / scale + turn * b) * dt / r
    increments = np.column_stack([left, right]) + rng.normal(size=(len(dt), 2)) * 1e-4
    return times, truth, increments, rng


def wandering_fixes(rng, times, truth, wander=0.3, white=0.05):
    """Fixes at ``FIX_RATE`` from ``sensors.absolute_readings``: the truth plus a random-walk
    offset (``wander`` m/sqrt(s)) plus white noise (``white`` m); the stamps, the fixes and
    the offsets."""
    model = AbsoluteModel(
        sigma=(white, white, 0.0), period=1.0 / FIX_RATE, position_only=True, wander=wander
    )
    seen = absolute_readings(ROBOT, times, truth, model, seed=int(rng.integers(2**31)))
    return seen.times, seen.poses[0, :, :2], seen.offsets[0]


def test_identify_fixes_finds_the_wander_the_white_noise_and_the_wheels_scale():
    """A receiver that wanders 0.3 m/sqrt(s) with 0.2 m of white noise, wheels over-reading
    distance by 3 %, eight seeds: the wander and the white noise within 30 % (over 50 seeds
    ``benchmarks/bench_fixes.py`` finds a median error of 5 %, a 90th percentile of 22 %), the
    distance scale and the start's heading within three of their standard errors (the wander
    leaves them loose here: 5 m over the drive), the start's position (the first fix, the
    offset's zero) within five of the white noise (seed 5's first fix is 3.8 sigma off)."""
    for seed in range(8):
        times, truth, increments, rng = drive(seed)
        stamps, fixes, _ = wandering_fixes(rng, times, truth, white=0.2)
        dead = estimate_trajectory(ROBOT, times, increments, settings=WHEELS, smooth=False)
        fit = identify_fixes(times, dead.poses, stamps, fixes)
        assert fit.wander == pytest.approx(0.3, rel=0.3)
        assert fit.white == pytest.approx(0.2, rel=0.3)
        assert abs(fit.fitted_scale - 0.97) < 3 * fit.scale_error
        assert np.hypot(*(fit.start[:2] - truth[0, :2])) < 5 * fit.white
        assert abs(fit.start[2] - truth[0, 2]) < 3 * math.sqrt(fit.start_covariance[2, 2])
        assert fit.report[0].startswith(f"fixes: white noise {fit.white:.3g} m")


def test_a_steady_receiver_gives_the_wheels_scale_to_a_percent():
    """A receiver that hardly wanders (2 cm/sqrt(s), 0.3 m white): the distance scale within
    1.5 % of 0.97, and within three of its standard errors."""
    for seed in range(4):
        times, truth, increments, rng = drive(seed)
        stamps, fixes, _ = wandering_fixes(rng, times, truth, wander=0.02, white=0.3)
        dead = estimate_trajectory(ROBOT, times, increments, settings=WHEELS, smooth=False)
        fit = identify_fixes(times, dead.poses, stamps, fixes)
        assert fit.fitted_scale == pytest.approx(0.97, rel=0.015)
        assert abs(fit.fitted_scale - 0.97) < 3 * fit.scale_error


def test_white_fixes_are_identified_as_white():
    """Fixes with 0.5 m of white noise and no wander: the white noise found within 20 %, the
    wander small beside it (under 0.05 m/sqrt(s))."""
    times, truth, increments, rng = drive(7, scale=1.0)
    stamps, fixes, _ = wandering_fixes(rng, times, truth, wander=0.0, white=0.5)
    dead = estimate_trajectory(ROBOT, times, increments, settings=WHEELS, smooth=False)
    fit = identify_fixes(times, dead.poses, stamps, fixes)
    assert fit.white == pytest.approx(0.5, rel=0.2)
    assert fit.wander < 0.05


def test_identified_fixes_follow_the_wander_where_white_ones_cannot():
    """One fix in four used, the rest left out: with the fixes identified, the smoother's
    prediction of the left-out fixes (its position plus the offset) is closer than with the
    fixes taken as white noise of the size their wander reaches over the log, and at most 2 %
    worse than interpolating the fixes used."""
    for seed in range(3):
        times, truth, increments, rng = drive(seed)
        stamps, fixes, offset = wandering_fixes(rng, times, truth)
        used = np.arange(len(stamps)) % 4 == 0
        left = ~used
        settings = S("wheels", wheel_noise=1e-4)
        identified = estimate_trajectory(
            ROBOT, times, increments,
            settings=settings.replace(whole_log=WholeLog(fixes="identified")),
            measurements=measurements_of("position", stamps[used], fixes[used], 1.0),
        )  # fmt: skip
        spread = float(np.std(offset))
        white = estimate_trajectory(
            ROBOT, times, increments, initial_pose=truth[0],
            measurements=measurements_of("position", stamps[used], fixes[used], spread),
            settings=settings,
        )  # fmt: skip
        assert identified.rejected == 0
        assert any(line.startswith("fixes: white noise") for line in identified.settings)

        between = np.column_stack(
            [np.interp(stamps[left], stamps[used], fixes[used, i]) for i in (0, 1)]
        )
        found = miss(predicted(identified, times, stamps[left]), fixes[left])
        assert found < 0.8 * miss(predicted(white, times, stamps[left]), fixes[left])
        assert found < 1.02 * miss(between, fixes[left])


@pytest.mark.parametrize(
    ("wander", "white"), [(0.3, 0.05), (0.02, 0.5), (0.3, 0.5)], ids=["wander", "white", "both"]
)
def test_sparse_fixes_help_at_every_gap_with_no_setting_given(wander, white):
    """Receivers that wander, that are white, and both, one fix in every 1 to 50 s used
    (down to 7 fixes over the 300 s drive), what they are worth identified from the used fixes
    alone: no fix refused, the smoother's fix (position plus offset) at most 2 % worse than
    interpolating the used fixes and at most 10 % worse than the dead reckoning through them
    (``evaluation.through_fixes``); at 50 s, with 7 fixes, at most 15 % (1.12 at worst over
    these seeds: the fit of four numbers to seven fixes is loose)."""
    from diffdrive.evaluation import through_fixes

    for seed in range(2):
        times, truth, increments, rng = drive(seed)
        stamps, fixes, _ = wandering_fixes(rng, times, truth, wander=wander, white=white)
        dead = estimate_trajectory(ROBOT, times, increments, settings=WHEELS, smooth=False)
        for gap, bound in ((1.0, 1.1), (4.0, 1.1), (10.0, 1.1), (20.0, 1.1), (50.0, 1.15)):
            used = np.arange(len(stamps)) % round(gap * FIX_RATE) == 0
            used[-1] = True
            left = ~used
            run = estimate_trajectory(
                ROBOT, times, increments, settings=IDENTIFIED,
                measurements=measurements_of("position", stamps[used], fixes[used], 1.0),
            )  # fmt: skip
            assert run.rejected == 0
            found = miss(predicted(run, times, stamps[left]), fixes[left])
            between = np.column_stack(
                [np.interp(stamps[left], stamps[used], fixes[used, i]) for i in (0, 1)]
            )
            carried = through_fixes(times, dead.poses, stamps[used], fixes[used], stamps[left])
            assert found <= 1.02 * miss(between, fixes[left]), (seed, gap)
            assert found <= bound * miss(carried, fixes[left]), (seed, gap)


def test_fixes_too_far_apart_hold_the_white_noise_at_its_prior():
    """Fixes 10 s apart cannot tell white noise from wander: the white noise is held at
    ``WHITE_PRIOR`` and the report says why; fixes 0.5 s apart identify it."""
    from diffdrive.estimation.fixes import WHITE_PRIOR

    times, truth, increments, rng = drive(1)
    stamps, fixes, _ = wandering_fixes(rng, times, truth, white=0.3)
    dead = estimate_trajectory(ROBOT, times, increments, settings=WHEELS, smooth=False)
    sparse = identify_fixes(times, dead.poses, stamps[::20], fixes[::20])
    assert sparse.white == WHITE_PRIOR
    assert "held at its prior: 30 fixes 10 s apart cannot tell it" in sparse.report[0]
    assert sparse.wander == pytest.approx(0.3, rel=0.5)
    dense = identify_fixes(times, dead.poses, stamps, fixes)
    assert dense.white == pytest.approx(0.3, rel=0.3)
    assert "held" not in dense.report[0]


def test_three_fixes_are_enough_and_two_are_refused_by_name():
    """The fit of four numbers needs three fixes to leave a residual: three are taken, two
    refused with what to give instead."""
    times, truth, increments, rng = drive(2)
    stamps, fixes, _ = wandering_fixes(rng, times, truth)
    dead = estimate_trajectory(ROBOT, times, increments, settings=WHEELS, smooth=False)
    picked = [0, 300, 599]
    assert identify_fixes(times, dead.poses, stamps[picked], fixes[picked]).fixes == 3
    with pytest.raises(ValueError, match="2 position fixes: at least 3 are needed"):
        identify_fixes(times, dead.poses, stamps[picked[:2]], fixes[picked[:2]])


def predicted(estimate, times, stamps):
    """Where an estimate puts the fixes at ``stamps``: its position plus the offset."""
    at = np.column_stack([np.interp(stamps, times, estimate.states[:, k]) for k in range(8)])
    return at[:, :2] + at[:, ekf.OFFSET : ekf.OFFSET + 2]


def miss(points, fixes):
    """The mean distance from ``points`` to ``fixes``, m."""
    return float(np.mean(np.hypot(*(points - fixes).T)))


def test_the_distance_scale_state_finds_the_wheels_scale_from_white_fixes():
    """Wheels over-reading by 3 %, white fixes of 0.3 m, the scale a state from 1 +- 0.1:
    it ends within three of its standard deviations of 0.97, and within 0.5 %."""
    times, truth, increments, rng = drive(3)
    stamps, fixes, _ = wandering_fixes(rng, times, truth, wander=0.0, white=0.3)
    estimate = estimate_trajectory(
        ROBOT, times, increments, initial_pose=truth[0],
        initial_covariance=np.diag([0.1, 0.1, 0.01]),
        measurements=measurements_of("position", stamps, fixes, 0.3),
        settings=S("wheels", wheel_noise=1e-4, distance_scale=Prior(sigma=0.1)),
    )  # fmt: skip
    found = estimate.states[-1, ekf.DISTANCE]
    sigma = math.sqrt(estimate.state_covariances[-1, ekf.DISTANCE, ekf.DISTANCE])
    assert abs(found - 0.97) < 3 * sigma
    assert found == pytest.approx(0.97, rel=0.005)


@pytest.mark.parametrize("core", [PoseEstimator, _PythonPoseEstimator])
def test_a_position_carries_the_offset_and_a_pose_does_not(core):
    """With the offset a state from 0 +- 1 m and the pose known to 1 mm, a position fix 0.5 m
    off moves the offset, not the pose; a pose measurement does not see the offset."""
    estimator = core(
        ROBOT, S("wheels", fix_offset=FixOffset(rate=0.1, sigma=1.0)), initial_pose=(0.0, 0.0, 0.0),
        initial_covariance=np.eye(3) * 1e-6, initial_time=0.0,
    )  # fmt: skip
    estimator.update_increments(0.0, 0.0, 0.1)
    assert estimator.add_position(0.1, (0.5, 0.0), 0.01)
    assert estimator.fix_offset[0] == pytest.approx(0.5, abs=0.01)
    assert estimator.pose.x == pytest.approx(0.0, abs=1e-3)
    before = estimator.fix_offset.copy()
    assert estimator.add_pose(0.1, (0.0, 0.0, 0.0), (0.01, 0.01, 0.01))
    np.testing.assert_allclose(estimator.fix_offset, before, atol=1e-6)
    assert estimator.distance_scale == 1.0


def test_an_outlier_past_the_gate_is_inflated_onto_it():
    """``outliers="inflate"``: a measurement past the gate is taken as one with covariance
    ``R + (a - 1) S`` (``a`` its score over the gate), which puts its score on the gate; with
    ``"refuse"`` it moves nothing."""
    x = np.zeros(ekf.N)
    x[ekf.SCALE] = x[ekf.DISTANCE] = 1.0
    P = np.diag([0.01, 0.01, 0.001, 0, 0, 0, 0, 0])
    m = Measurement.make("position", 0.0, (1.0, -0.5), 0.05)
    gate = {1: 3.84, 2: 5.99, 3: 7.81}
    kept, _, ok, score, log_det = ekf.absolute_update(x, P, m, 0.0, gate)
    assert not ok
    assert np.array_equal(kept, x)
    assert score > gate[2]
    S = P[:2, :2] + m.covariance
    assert log_det == pytest.approx(math.log(np.linalg.det(S)))
    moved, P_moved, ok, _, _ = ekf.absolute_update(x, P, m, 0.0, gate, inflate=True)
    assert ok
    grow = score / gate[2]
    R = m.covariance + (grow - 1.0) * S
    gain = P[:, :2] @ np.linalg.inv(P[:2, :2] + R)
    np.testing.assert_allclose(moved, x + gain @ np.array([1.0, -0.5]), atol=1e-12)
    innovation = np.array([1.0, -0.5])
    assert innovation @ np.linalg.solve(P[:2, :2] + R, innovation) == pytest.approx(gate[2])
    expected = (np.eye(ekf.N) - gain[:, :] @ np.eye(2, ekf.N)) @ P
    np.testing.assert_allclose(P_moved, 0.5 * (expected + expected.T), atol=1e-12)


def test_the_log_likelihood_is_the_innovations_gaussian_density():
    """One position fix at the start, against a start known to (0.2, 0.3) m: the log
    likelihood is the Gaussian density of the fix's miss under the start's covariance plus
    the fix's."""
    times = np.array([0.0, 0.1])
    fix = measurements_of("position", [0.0], [(0.3, -0.2)], 0.1)
    estimate = estimate_trajectory(
        ROBOT, times, np.zeros((1, 2)), settings=WHEELS, measurements=fix,
        initial_covariance=np.diag([0.04, 0.09, 0.01]),
    )  # fmt: skip
    S = np.diag([0.04 + 0.01, 0.09 + 0.01])
    away = np.array([0.3, -0.2])
    want = -0.5 * (
        away @ np.linalg.solve(S, away) + math.log(np.linalg.det(S)) + 2 * math.log(2 * math.pi)
    )
    assert estimate.log_likelihood == pytest.approx(want, rel=1e-12)


def test_fixes_that_cannot_be_identified_are_refused_by_name():
    """Too few fixes, or a robot that stands still: the message says what is missing and
    what to give; a bad fixes or outliers setting is named."""
    times = np.arange(0.0, 10.0, 0.1)
    still = np.zeros((len(times) - 1, 2))
    few = measurements_of("position", times[:2], np.zeros((2, 2)), 0.5)
    with pytest.raises(ValueError, match="2 position fixes: at least 3"):
        estimate_trajectory(ROBOT, times, still, settings=IDENTIFIED, measurements=few)
    many = measurements_of("position", times[::5], np.zeros((20, 2)), 0.5)
    with pytest.raises(ValueError, match="hardly moves"):
        estimate_trajectory(ROBOT, times, still, settings=IDENTIFIED, measurements=many)
    with pytest.raises(ValueError, match=r"WholeLog\.fixes must be one of given, identified"):
        WholeLog(fixes="auto")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"Gate\.outliers must be one of refuse, inflate"):
        Gate(outliers="keep")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"FixOffset\.rate must be >= 0"):
        FixOffset(rate=-0.1)
    with pytest.raises(ValueError, match=r"Prior\.start must be"):
        Prior(0.0)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (
            lambda f: np.where(np.arange(len(f))[:, None] == 3, np.nan, f),
            "fixes must be finite: row 3",
        ),
        (lambda f: np.full_like(f, 5.0), "the fixes hardly move \\(0 m RMS"),
        (lambda f: f[:, :1], "fix_times \\(M,\\) and fixes \\(M, 2\\) m must match"),
    ],
    ids=["a NaN fix", "a receiver that never moves", "fixes of one column"],
)
def test_identify_fixes_names_what_is_wrong(change, message):
    """A NaN fix, a receiver that never moves and a wrong shape were taken without a word (a
    NaN or zero scale): each is refused by name."""
    from diffdrive.estimation.fixes import identify_fixes

    t = np.linspace(0.0, 100.0, 1001)
    poses = np.column_stack([0.5 * t, np.sin(t / 10), np.zeros_like(t)])
    fixes = poses[::10, :2] + np.random.default_rng(0).normal(0.0, 0.5, (101, 2))
    assert identify_fixes(t, poses, t[::10], fixes).report  # the good case is taken
    with pytest.raises(ValueError, match=message):
        identify_fixes(t, poses, t[::10], change(fixes))
