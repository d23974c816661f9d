"""One table of integration cases through every backend that integrates a driving history.

Every method, axle offsets, turns on both sides of the sinc threshold, straight runs and spins,
float32 and float64, and a long run, each held to a plain loop of the scalar step
(``integrate.step``, seed 000's recurrence for euler): ``simulate`` (NumPy prefix sums and the
numba kernel), ``Odometry`` (the C update and its pure-Python twin), ``estimate_trajectory``'s
whole-log pass (both cores, filtered and smoothed), the gyro filter with the heading from the
wheels and from a perfect gyro, the Monte Carlo kernel with no noise, and
``batch.rollout`` and ``simulate`` in NumPy, array-api-strict, JAX and PyTorch. Then JAX's
gradient of a final-pose loss with respect to the geometry, against finite differences.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import pytest

import diffdrive as dd
from diffdrive import batch, integrate
from diffdrive.estimation import (
    COMPILED,
    EstimatorSettings,
    GyroOdometry,
    PoseEstimator,
    estimate_trajectory,
    smoother,
)
from diffdrive.estimation.fusion import _PythonPoseEstimator
from diffdrive.estimation.odometry import _PythonOdometry
from diffdrive.montecarlo import monte_carlo
from optional import Library

jax, jnp = Library("jax"), Library("jax.numpy")
torch, xps = Library("torch"), Library("array_api_strict")


@dataclass(frozen=True, eq=False)  # hashed by identity, for the cache of the reference
class Case:
    name: str
    robot: dd.DiffDrive
    wheels: np.ndarray  # (T, 2) rad/s
    dt: float
    start: tuple[float, float, float] = (0.3, -0.2, 0.7)


def _weave(steps: int, dt: float) -> np.ndarray:
    t = np.arange(steps) * dt
    return np.stack([8 + 5 * np.sin(0.9 * t), 8 - 5 * np.sin(0.6 * t + 1)], axis=-1)


ROBOT = dd.DiffDrive(0.05, 0.3)
OFFSET = dd.DiffDrive(
    left_wheel_radius=0.049, right_wheel_radius=0.051, track_width=0.31, axle_offset=0.07
)
CASES = [
    Case("weave", ROBOT, _weave(200, 0.02), 0.02),
    Case("weave, axle offset", OFFSET, _weave(200, 0.02), 0.02),
    # A turn per step of 1e-5 rad: far below sinc's Taylor threshold (9e-3 rad in float64).
    Case("tiny turns", ROBOT, np.tile([10.0, 10.0 + 3e-3], (100, 1)), 0.01),
    # 0.5 rad a step: far above it, where the three methods differ most.
    Case("sharp turns", OFFSET, np.tile([-5.0, 25.0], (60, 1)), 0.1),
    Case("straight", ROBOT, np.tile([7.0, 7.0], (50, 1)), 0.05),
    Case("spin in place", OFFSET, np.tile([-6.0, 6.0], (50, 1)), 0.05),
    Case("long run", OFFSET, _weave(20_000, 0.005), 0.005),
]


@functools.cache
def loop(case: Case, method: str) -> np.ndarray:
    """The reference: the scalar step, one pose after another."""
    pose, poses = dd.Pose(*case.start), [case.start]
    for wheels in case.wheels:
        pose = integrate.step(pose, case.robot.to_twist(wheels), case.dt, method)
        poses.append(pose.to_array())
    return np.array(poses)


def _simulate(backend):
    def run(case, method, dtype):
        wheels = case.wheels.astype(dtype)
        return dd.simulate(
            case.robot, wheels, dt=case.dt, initial_pose=case.start, method=method, backend=backend
        ).poses

    return run


def _simulate_in(convert):
    """simulate on another library's history: the Trajectory stays in that library."""

    def run(case, method, dtype):
        wheels = convert(case.wheels.astype(dtype))
        start = convert(np.array(case.start, dtype=dtype))
        trajectory = dd.simulate(case.robot, wheels, dt=case.dt, method=method, initial_pose=start)
        assert type(trajectory.poses) is type(wheels)
        return np.asarray(trajectory.poses)

    return run


def _odometry(kind):
    def run(case, method, dtype):
        odometry = kind(case.robot, method, initial_pose=dd.Pose(*case.start))
        poses, _ = odometry.update_arrays("increments", *(case.wheels * case.dt).T)
        return np.concatenate([[case.start], poses])

    return run


def _gyro(heading):
    """The gyro filter, its heading from the wheels, or from a gyro that turns exactly as the
    wheels do (the turn from the robot's own forward kinematics, no bias)."""

    def run(case, method, dtype):
        settings = EstimatorSettings(heading, method=method)
        filter = GyroOdometry(case.robot, settings, initial_pose=dd.Pose(*case.start))
        poses = [case.start]
        for left, right in case.wheels * case.dt:
            turn = case.robot.to_twist((left, right)).omega
            filter.update(left, right, turn, 1.0)
            poses.append(filter.pose.to_array())
        return np.array(poses)

    return run


def _estimator(kind):
    """PoseEstimator (its C core, or its pure-Python twin), heading from the wheels, fed
    accumulated wheel angles as a log gives them (the first reading is the reference)."""

    def run(case, method, dtype):
        settings = EstimatorSettings("wheels", method=method)
        estimator = kind(case.robot, settings, initial_pose=dd.Pose(*case.start))
        positions = np.concatenate([[[0.0, 0.0]], np.cumsum(case.wheels * case.dt, axis=0)])
        poses = []
        for k, (left, right) in enumerate(positions):
            estimator.update_positions(left, right, float(k))
            poses.append(estimator.pose.to_array())
        return np.array(poses)

    return run


def _whole_log(kind, smooth):
    """estimate_trajectory's pass over the whole log (the C core's ``_run_log`` or its twin's),
    heading from the wheels; with no measurement the smoother gives the filter's path back."""

    def run(case, method, dtype):
        times = np.arange(len(case.wheels) + 1) * case.dt
        with pytest.MonkeyPatch.context() as patch:
            patch.setattr(smoother, "PoseEstimator", kind)
            estimate = estimate_trajectory(
                case.robot, times, case.wheels * case.dt, initial_pose=case.start,
                settings=EstimatorSettings("wheels", method=method), smooth=smooth,
            )  # fmt: skip
        return estimate.poses

    return run


def _monte_carlo(case, method, dtype):
    result = monte_carlo(
        case.robot,
        case.wheels,
        case.dt,
        1,
        initial_pose=case.start,
        method=method,
        backend="numba",
        seed=0,
    )
    return result.mean  # one robot and no noise: its path


def _rollout(convert, rollout=batch.rollout):
    def run(case, method, dtype):
        poses = rollout(
            case.robot,
            convert(case.wheels.astype(dtype)),
            case.dt,
            convert(np.array(case.start, dtype=dtype)),
            method,
        )
        return np.asarray(poses)

    return run


def _jax_array(values: np.ndarray):
    return jnp.asarray(values)


def _torch_array(values: np.ndarray):
    return torch.asarray(values)


def _strict_array(values: np.ndarray):
    return xps.asarray(values)


@functools.cache
def _jitted_rollout():
    return jax.jit(batch.rollout, static_argnums=(0, 2, 4))


def _jax_rollout(*args):
    return _jitted_rollout()(*args)


BACKENDS = {
    "simulate numpy": (_simulate("numpy"), ("float32", "float64")),
    "simulate numba": (_simulate("numba"), ("float32", "float64")),
    "odometry (C)": (_odometry(dd.Odometry), ("float64",)),
    "odometry (pure Python)": (_odometry(_PythonOdometry), ("float64",)),
    "gyro filter, wheel heading": (_gyro("wheels"), ("float64",)),
    "gyro filter, gyro heading": (_gyro("gyro"), ("float64",)),
    "pose estimator (C), wheel heading": (_estimator(PoseEstimator), ("float64",)),
    "pose estimator (pure Python), wheel heading": (_estimator(_PythonPoseEstimator), ("float64",)),
    "whole log (C)": (_whole_log(PoseEstimator, False), ("float64",)),
    "whole log (pure Python)": (_whole_log(_PythonPoseEstimator, False), ("float64",)),
    "whole log smoothed (C)": (_whole_log(PoseEstimator, True), ("float64",)),
    "monte carlo (numba)": (_monte_carlo, ("float64",)),
    "rollout numpy": (_rollout(np.asarray), ("float32", "float64")),
    "rollout array-api-strict": (_rollout(_strict_array), ("float32", "float64")),
    # Compiled as a whole (as JAX users run it), not one primitive at a time.
    "rollout jax": (
        _rollout(_jax_array, _jax_rollout),
        ("float32", "float64"),
    ),
    "rollout torch": (_rollout(_torch_array), ("float32", "float64")),
    "simulate array-api-strict": (_simulate_in(_strict_array), ("float32", "float64")),
    "simulate jax": (_simulate_in(_jax_array), ("float32", "float64")),
    "simulate torch": (_simulate_in(_torch_array), ("float32", "float64")),
}


@pytest.fixture(autouse=True, scope="module")
def jax_in_float64():
    """JAX keeps float64 only when asked; the table wants both dtypes."""
    jax.config.update("jax_enable_x64", True)
    yield
    jax.config.update("jax_enable_x64", False)


def _tolerance(case: Case, dtype: str, backend: str) -> float:
    """Absolute, m or rad: rounding over the path, by dtype and summation."""
    length = float(np.sum(np.abs(case.wheels).max(axis=1) * case.robot.wheel_radius * case.dt))
    scale = 1.0 + length + float(np.sum(np.abs(np.diff(case.wheels, axis=1))))
    if dtype == "float32":
        # Plain float32 prefix sums lose about sqrt(T) ulps; simulate sums in float64.
        steps = len(case.wheels)
        blocked = backend in ("simulate numpy", "simulate numba")
        return 2e-6 * scale * (1.0 if blocked else np.sqrt(steps))
    return 1e-11 * scale


# The long run and the other array libraries (their first calls compile) take 0.2-2 s each.
OTHER_LIBRARY = ("jax", "torch", "array-api-strict")


@pytest.mark.parametrize(
    "backend",
    [
        pytest.param(name, marks=pytest.mark.slow) if name.endswith(OTHER_LIBRARY) else name
        for name in BACKENDS
    ],
)
@pytest.mark.parametrize("method", integrate.METHODS)
@pytest.mark.parametrize(
    "case",
    [pytest.param(c, id=c.name, marks=[pytest.mark.slow] * (c.name == "long run")) for c in CASES],
)
def test_every_backend_follows_the_scalar_step(case, method, backend):
    run, dtypes = BACKENDS[backend]
    want = loop(case, method)
    for dtype in dtypes:
        got = run(case, method, dtype)
        assert got.shape == want.shape, (backend, dtype)
        np.testing.assert_allclose(
            got, want, rtol=0, atol=_tolerance(case, dtype, backend), err_msg=f"{backend}, {dtype}"
        )


# How to make an array of each library other than NumPy, and its type.
OTHER_LIBRARIES = {
    "torch": (_torch_array, lambda: torch.Tensor),
    "array-api-strict": (_strict_array, lambda: type(xps.asarray(0.0))),
    "jax": (_jax_array, lambda: jax.Array),
}


def test_the_c_core_was_built_here():
    assert COMPILED, "the C extension is missing: Odometry runs on its pure-Python twin"


@pytest.mark.slow
@pytest.mark.parametrize("library", OTHER_LIBRARIES)
def test_results_stay_in_the_callers_library(library):
    convert, kind = OTHER_LIBRARIES[library][0], OTHER_LIBRARIES[library][1]()
    wheels = convert(_weave(10, 0.1).astype(np.float32))
    poses = batch.rollout(ROBOT, wheels, 0.1)
    assert isinstance(poses, kind)
    assert poses.dtype == wheels.dtype
    increments = batch.to_twist(ROBOT, wheels) * 0.1
    assert isinstance(dd.simulation.integrate_increments(increments), kind)
    with pytest.raises(ValueError, match="dtype is for NumPy"):
        dd.simulation.integrate_increments(increments, dtype=np.float64)


@pytest.mark.slow
@pytest.mark.parametrize("library", OTHER_LIBRARIES)
def test_a_trajectory_of_another_library_derives_everything_in_it(library):
    """simulate's Trajectory of a batch of robots, each property against NumPy's."""
    convert, kind = OTHER_LIBRARIES[library][0], OTHER_LIBRARIES[library][1]()
    wheels = np.stack([_weave(40, 0.05), _weave(40, 0.05)[::-1]])  # (2, 40, 2)
    start = np.array([[0.0, 0.0, 0.0], [1.0, -1.0, 2.0]])
    times = np.concatenate([[0.0], np.cumsum(np.linspace(0.03, 0.07, 40))])
    want = dd.simulate(OFFSET, wheels, times=times, initial_pose=start, method="rk2")
    got = dd.simulate(
        OFFSET, convert(wheels), times=convert(times), initial_pose=convert(start), method="rk2"
    )
    for name in (
        "times",
        "poses",
        "durations",
        "twists",
        "wheel_positions",
        "final_pose",
        "wrapped_headings",
        "distance",
    ):
        value = getattr(got, name)
        assert isinstance(value, kind), name
        np.testing.assert_allclose(np.asarray(value), getattr(want, name), atol=1e-12, err_msg=name)
    at = np.array([0.0, 0.31, 1.0, times[-1]])
    np.testing.assert_allclose(np.asarray(got.sample(convert(at))), want.sample(at), atol=1e-12)
    np.testing.assert_allclose(np.asarray(got.to_array()), want.to_array(), atol=1e-12)
    angles = dd.simulate(
        OFFSET,
        wheel_positions=convert(want.wheel_positions),
        method="rk2",
        times=convert(times),
        initial_pose=convert(start),
    )
    np.testing.assert_allclose(np.asarray(angles.poses), want.poses, atol=1e-12)
    assert "final_pose=<(2, 3) array>" in repr(got)


def test_another_librarys_bad_history_is_named_as_numpys_is():
    wheels = np.ones((5, 2))
    wheels[3, 1] = np.nan
    with pytest.raises(
        ValueError, match=r"wheel_velocities must be finite, got nan at index \(3, 1\)"
    ):
        dd.simulate(ROBOT, torch.asarray(wheels), dt=0.1)
    with pytest.raises(ValueError, match=r"times must increase strictly; times\(2,\) = 0\.1"):
        dd.simulate(ROBOT, xps.asarray(np.ones((3, 2))), times=xps.asarray([0.0, 0.2, 0.1, 0.3]))
    with pytest.raises(ValueError, match="backend='numba' takes NumPy arrays"):
        dd.simulate(ROBOT, torch.ones((3, 2), dtype=torch.float64), dt=0.1, backend="numba")


def test_an_array_geometry_broadcasts_one_robot_per_row():
    wheels = _weave(50, 0.02)
    geometry = np.array([[0.05, 0.05, 0.3, 0.0], [0.049, 0.051, 0.31, 0.07]])
    poses = batch.rollout(geometry, wheels, 0.02)
    assert poses.shape == (2, 51, 3)
    np.testing.assert_allclose(poses[1], batch.rollout(OFFSET, wheels, 0.02), atol=1e-14)
    with pytest.raises(ValueError, match=r"geometry must have shape \(\.\.\., 3\) or"):
        batch.rollout(np.ones(5), wheels, 0.02)
    with pytest.raises(ValueError, match="dt must be finite and > 0"):
        batch.rollout(ROBOT, wheels, 0.0)


@pytest.mark.slow
def test_jax_differentiates_a_final_pose_loss_with_respect_to_the_geometry():
    wheels = jnp.asarray(_weave(300, 0.02))
    target = jnp.asarray([1.0, 0.5, 0.3])

    def loss(geometry):
        final = batch.rollout(geometry, wheels, 0.02)[-1]
        return jnp.sum((final - target) ** 2)

    geometry = jnp.asarray([0.05, 0.051, 0.3, 0.01])
    gradient = np.asarray(jax.jit(jax.grad(loss))(geometry))
    value, step = jax.jit(loss), 1e-6
    differences = [
        (value(geometry.at[i].add(step)) - value(geometry.at[i].add(-step))) / (2 * step)
        for i in range(4)
    ]
    np.testing.assert_allclose(gradient, np.asarray(differences), rtol=1e-6, atol=1e-8)
    assert np.all(np.abs(gradient) > 1e-3)  # every parameter moves the final pose
