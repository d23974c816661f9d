"""Stateful property tests: random sequences of calls on Odometry, Limiter,
OpenLoopOdometry, OnlineCalibrator, GyroOdometry and PoseEstimator, each checked against a
twin that sees only the calls that were accepted.

A refused call must raise ValueError or TypeError and leave the object exactly as its twin;
an accepted one must leave a finite state that every reading returns. The values drawn reach
the edges that broke these objects before: 1e308, huge integers, tiny and huge dt.
"""

import math

import numpy as np
import pytest
from hypothesis import settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, invariant, rule

import diffdrive as dd
from diffdrive.calibration import OnlineCalibrator
from diffdrive.estimation import Encoders, EstimatorSettings, PoseEstimator, Window
from diffdrive.estimation.fusion import _PythonPoseEstimator
from diffdrive.estimation.gyro import GyroOdometry

ROBOT = dd.DiffDrive(
    left_wheel_radius=0.05, right_wheel_radius=0.051, track_width=0.3, axle_offset=0.02
)
EDGE = [
    0.0,
    1e-300,
    -1e-300,
    1e-9,
    1.0,
    -1.0,
    1e6,
    -1e6,
    1e160,
    -1e160,
    1e300,
    1e308,
    -1e308,
    math.inf,
    math.nan,
]
numbers = st.one_of(
    st.sampled_from(EDGE), st.floats(-1e3, 1e3), st.integers(-5, 5), st.just(10**400)
)
times = st.one_of(st.floats(-1.0, 1e3), st.sampled_from([1e308, 1e-300, math.inf, math.nan]))
steps = st.one_of(st.floats(1e-6, 10.0), st.sampled_from([1e-300, 1e308, 0.0, -0.1, math.nan]))
REFUSED = (ValueError, TypeError)
SETTINGS = settings(max_examples=60, stateful_step_count=25)
pytestmark = pytest.mark.slow  # each machine about a second


def attempt(call):
    """Run ``call``; True if accepted, False if refused as documented (anything else fails)."""
    try:
        call()
    except REFUSED:
        return False
    return True


def odometry_state(odometry):
    pose = odometry.pose.to_array()
    return (*pose, odometry.distance, odometry.time, *odometry.covariance.ravel())


def same(a, b):
    return all((x == y) or (x != x and y != y) for x, y in zip(a, b, strict=True))


class OdometryMachine(RuleBasedStateMachine):
    def __init__(self):
        super().__init__()
        options = {
            "ticks_per_revolution": 4096,
            "counter_bits": 16,
            "max_wheel_speed": 1e4,
            "wheel_noise": 1e-4,
        }
        self.odometry, self.twin = dd.Odometry(ROBOT, **options), dd.Odometry(ROBOT, **options)

    def apply(self, name, *args):
        if attempt(lambda: getattr(self.odometry, name)(*args)):
            getattr(self.twin, name)(*args)  # the twin accepts what the object accepted
        assert same(odometry_state(self.odometry), odometry_state(self.twin))

    @rule(left=numbers, right=numbers, t=st.one_of(st.none(), times))
    def increments(self, left, right, t):
        self.apply("update_increments", left, right, t)

    @rule(left=numbers, right=numbers, t=st.one_of(st.none(), times))
    def positions(self, left, right, t):
        self.apply("update_positions", left, right, t)

    @rule(left=numbers, right=numbers, dt=steps)
    def velocities(self, left, right, dt):
        self.apply("update_velocities", left, right, dt)

    @rule(
        left=st.integers(-(2**16), 2**17),
        right=st.integers(-(2**16), 2**17),
        t=st.one_of(st.none(), times),
    )
    def ticks(self, left, right, t):
        self.apply("update_ticks", left, right, t)

    @invariant()
    def readable_and_finite(self):
        state = odometry_state(self.odometry)
        assert all(math.isfinite(v) for k, v in enumerate(state) if k != 4)  # 4: the clock
        assert self.odometry.time is None or math.isfinite(self.odometry.time)


class LimiterMachine(RuleBasedStateMachine):
    LIMITS = (
        dd.Limits(max_velocity=2.0, max_acceleration=4.0, max_jerk=33.0),
        dd.Limits(max_reverse_velocity=2.0, max_jerk=33.0),
    )

    def __init__(self):
        super().__init__()
        self.limiter, self.twin = dd.Limiter(self.LIMITS, 1.0), dd.Limiter(self.LIMITS, 1.0)
        self.output = np.zeros(2)

    @rule(goal=st.one_of(st.none(), st.tuples(numbers, numbers)), dt=steps)
    def step(self, goal, dt):
        try:
            self.output = self.limiter.step(goal, dt)
        except REFUSED:
            pass
        else:
            self.twin.step(goal, dt)
        for name in ("value", "acceleration", "_target", "_since_target"):
            np.testing.assert_array_equal(getattr(self.limiter, name), getattr(self.twin, name))

    @invariant()
    def within_the_velocity_limits_and_finite(self):
        assert np.all(np.isfinite(self.limiter.value))
        assert np.all(np.isfinite(self.limiter.acceleration))
        assert -2.0 <= self.output[0] <= 2.0
        assert self.output[1] >= -2.0


class OpenLoopMachine(RuleBasedStateMachine):
    def __init__(self):
        super().__init__()

        def make():
            limiter = dd.Limiter.for_twist(dd.Limits(), dd.Limits(max_jerk=50.0), timeout=0.5)
            return dd.OpenLoopOdometry(ROBOT, limiter, max_wheel_velocity=1e6)

        self.open_loop, self.twin = make(), make()

    @rule(command=st.one_of(st.none(), st.tuples(numbers, numbers)), dt=steps)
    def update(self, command, dt):
        if attempt(lambda: self.open_loop.update(command, dt)):
            self.twin.update(command, dt)
        ours, theirs = self.open_loop._path.limiter, self.twin._path.limiter
        np.testing.assert_array_equal(ours.value, theirs.value)
        np.testing.assert_array_equal(ours.acceleration, theirs.acceleration)
        assert same(odometry_state(self.open_loop.odometry), odometry_state(self.twin.odometry))

    @invariant()
    def finite(self):
        assert all(math.isfinite(v) for v in self.open_loop.pose.to_array())


class OnlineCalibratorMachine(RuleBasedStateMachine):
    def __init__(self):
        super().__init__()
        self.online = OnlineCalibrator(ROBOT, window=3, gate=1e12)
        self.twin = OnlineCalibrator(ROBOT, window=3, gate=1e12)

    @rule(left=numbers, right=numbers, pose=st.tuples(numbers, numbers, numbers))
    def update(self, left, right, pose):
        if attempt(lambda: self.online.update(left, right, pose)):
            self.twin.update(left, right, pose)
        state = (*self.online.parameters, *self.online.covariance.ravel())
        twin = (*self.twin.parameters, *self.twin.covariance.ravel())
        assert same(state, twin)
        assert self.online._gathered[2] == self.twin._gathered[2]

    @invariant()
    def finite(self):
        assert np.all(np.isfinite(self.online.parameters))
        assert np.all(np.isfinite(self.online.covariance))


class GyroOdometryMachine(RuleBasedStateMachine):
    """The gyro filter, fused and with the gyro's heading, on any update: refused ones leave
    it as its twin; accepted ones leave a finite pose, bias and covariance."""

    def __init__(self):
        super().__init__()
        headings = [EstimatorSettings("fused"), EstimatorSettings("gyro")]
        self.filters = [GyroOdometry(ROBOT, settings) for settings in headings]
        self.twins = [GyroOdometry(ROBOT, settings) for settings in headings]

    @rule(left=numbers, right=numbers, angle=numbers, dt=steps)
    def update(self, left, right, angle, dt):
        for ours, twin in zip(self.filters, self.twins, strict=True):
            if attempt(lambda o=ours: o.update(left, right, angle, dt)):
                twin.update(left, right, angle, dt)
            assert same(
                (*ours.state, *ours.covariance4.ravel()), (*twin.state, *twin.covariance4.ravel())
            )

    @invariant()
    def finite(self):
        for ours in self.filters:
            assert np.all(np.isfinite(ours.state))
            assert np.all(np.isfinite(ours.covariance))


class _PoseEstimatorMachine(RuleBasedStateMachine):
    """The estimator on 8-bit ticks, a gyro and absolute measurements, stamps anywhere:
    refused calls leave it as its twin, state, covariance, counts and history alike."""

    KIND: type = PoseEstimator

    def __init__(self):
        super().__init__()
        settings = EstimatorSettings(
            encoders=Encoders(100, 8, max_wheel_speed=1e4), window=Window(history=2.0)
        )
        self.ours = self.KIND(ROBOT, settings)
        self.twin = self.KIND(ROBOT, settings)

    def same(self):
        ours, twin = self.ours, self.twin
        return (
            same(
                (*ours.state, *ours.state_covariance.ravel()),
                (*twin.state, *twin.state_covariance.ravel()),
            )
            and (ours.accepted, ours.rejected, ours.time)
            == (twin.accepted, twin.rejected, twin.time)
            and ours.history_start == twin.history_start
        )

    @rule(left=numbers, right=numbers, t=times, rate=numbers)
    def ticks(self, left, right, t, rate):
        if attempt(lambda: self.ours.update_ticks(left, right, t, gyro_rate=rate)):
            self.twin.update_ticks(left, right, t, gyro_rate=rate)
        assert self.same()

    @rule(t=times, x=numbers, sigma=numbers, kind=st.sampled_from(["pose", "position"]))
    def measure(self, t, x, sigma, kind):
        value = (x, 0.0, 0.0)[: 3 if kind == "pose" else 2]
        add = self.ours.add_pose if kind == "pose" else self.ours.add_position
        if attempt(lambda: add(t, value, sigma)):
            (self.twin.add_pose if kind == "pose" else self.twin.add_position)(t, value, sigma)
        assert self.same()

    @invariant()
    def finite(self):
        assert np.all(np.isfinite(self.ours.state))
        assert np.all(np.isfinite(self.ours.state_covariance))


class PoseEstimatorMachine(_PoseEstimatorMachine):
    KIND = PoseEstimator  # the C core where it was built


class PythonPoseEstimatorMachine(_PoseEstimatorMachine):
    KIND = _PythonPoseEstimator


TestOdometryMachine = SETTINGS(OdometryMachine).TestCase
TestLimiterMachine = SETTINGS(LimiterMachine).TestCase
TestOpenLoopMachine = SETTINGS(OpenLoopMachine).TestCase
TestOnlineCalibratorMachine = SETTINGS(OnlineCalibratorMachine).TestCase
TestGyroOdometryMachine = SETTINGS(GyroOdometryMachine).TestCase
TestPoseEstimatorMachine = SETTINGS(PoseEstimatorMachine).TestCase
TestPythonPoseEstimatorMachine = SETTINGS(PythonPoseEstimatorMachine).TestCase
