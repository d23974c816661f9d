"""MPPI: the update on a problem whose optimum is known, the compiled sampler's normals, one
table of cases through every backend, tracking through a known delay and lag, obstacle
courses on fixed seeds, maps, and bad input refused by name with the controller unchanged."""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import diffdrive as dd
from diffdrive.control import (
    MPPI,
    Arrival,
    Avoidance,
    FollowSettings,
    MPPICosts,
    MPPISampling,
    Obstacles,
    PathLimits,
    WheelLimits,
    cluttered_corridor,
    follow,
    guide,
    plan,
    read_map,
)
from diffdrive.control._mppi_arrays import ArrayCycle, drive_period, feasible_commands, to_numpy
from diffdrive.control.mppi import settings as mppi_settings
from diffdrive.control.mppi import weighted_update
from diffdrive.dynamics import DriveModel, Feedforward
from optional import Library


@functools.cache
def compiled():
    """The compiled cycle's module, imported at a test's first use rather than at collection
    (numba's import takes most of a second); the test is skipped without numba."""
    return pytest.importorskip("diffdrive.backends.numba_mppi", reason="numba is optional")


LIBRARIES = {"torch": Library("torch"), "jax": Library("jax")}

ROBOT = dd.DiffDrive(wheel_radius=0.1, track_width=0.6)
FOOTPRINT = 0.35
LIMITS = PathLimits(max_velocity=1.0, max_acceleration=1.0, max_wheel_velocity=12.0)
FEEDFORWARD = Feedforward(0.5, 0.78, 0.06)  # the robot: kS V, kV V s/rad, kA V s^2/rad


def test_the_update_is_the_weighted_mean_a_gaussian_works_out_to():
    """Perturbations e ~ N(0, s^2), costs (e - c)^2: weights exp(-(e - c)^2 / T) times the
    sampling density make a Gaussian whose mean is c s^2 / (s^2 + T / 2)."""
    rng = np.random.default_rng(0)
    sigma, temperature, target = 1.0, 1.0, 0.6
    noise = rng.normal(0.0, sigma, (400_000, 1))
    step, weights = weighted_update((noise[:, 0] - target) ** 2, noise, temperature)
    assert step[0] == pytest.approx(target * sigma**2 / (sigma**2 + temperature / 2), abs=5e-3)
    assert weights.sum() == pytest.approx(1.0)
    # A cost that does not depend on the sample: the plain mean of the perturbations.
    flat, _ = weighted_update(np.full(1000, 3.0), noise[:1000], temperature)
    assert flat[0] == pytest.approx(noise[:1000, 0].mean())


def test_the_compiled_update_is_the_same_weighted_mean():
    rng = np.random.default_rng(1)
    noise = rng.normal(size=(30, 2, 500)).astype(np.float32)
    costs = rng.uniform(0.0, 3.0, 500)
    step = np.empty((30, 2))
    weights = compiled().update(costs, noise, 0.2, step)
    expected, reference = weighted_update(costs, np.moveaxis(noise, 2, 0).astype(float), 0.2)
    np.testing.assert_allclose(step, expected, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(weights, reference, rtol=1e-12)


def _q(drive: DriveModel | None = None, **costs: float):
    """The cycle's numbers for a cluttered course's plan, with every term switched on."""
    course = cluttered_corridor(np.random.default_rng(3))
    limits = PathLimits(
        max_velocity=1.0, max_acceleration=1.0, max_wheel_velocity=12.0,
        max_wheel_acceleration=20.0, max_voltage=6.0, feedforward=Feedforward(0.5, 0.5, 0.1),
    )  # fmt: skip
    path = plan([course.start, course.goal], ROBOT, limits)
    weights = MPPICosts(goal=1.0, progress=3.0, **costs)
    drive = drive or DriveModel(delay=0.1, time_constant=0.1, max_acceleration=30.0)
    tracker = MPPI(
        drive=drive, costs=weights, avoid=Avoidance(course.obstacles, footprint=FOOTPRINT)
    )
    return mppi_settings(tracker, path), path, course


def test_the_compiled_sampler_draws_standard_normals_per_candidate_stream():
    """The ziggurat's normals: a Kolmogorov-Smirnov test, the sigmas, no correlation between
    steps or candidates, and each candidate's stream its own (the first 64 candidates draw the
    same whether 64 or 4096 are drawn: the threads do not matter)."""
    from scipy import stats

    q, _, course = _q()
    mean, reference = np.zeros((50, 2)), np.tile([0.0, 0.0, 1.0, 0.0], (50, 1))
    state = compiled().in_flight(np.zeros(3), np.zeros(2), np.zeros((0, 2)), q)
    big = np.empty((50, 2, 4096), dtype=np.float32)
    compiled().cycle(mean, q, state, reference, course.obstacles.clearance, np.uint64(7), True,
                     big, np.empty(4096))  # fmt: skip
    small = np.empty((50, 2, 64), dtype=np.float32)
    compiled().cycle(mean, q, state, reference, course.obstacles.clearance, np.uint64(7), True,
                     small, np.empty(64))  # fmt: skip
    np.testing.assert_array_equal(small, big[:, :, :64])
    normals = big / np.array([q.sigma_v, q.sigma_omega])[None, :, None]
    for row in (normals[:, 0].ravel(), normals[:, 1].ravel()):
        assert stats.kstest(row, "norm").pvalue > 1e-3
        assert abs(row.mean()) < 5 * row.std() / math.sqrt(row.size)
    assert np.abs(np.corrcoef(normals[1:, 0].ravel(), normals[:-1, 0].ravel())[0, 1]) < 0.01
    assert np.abs(np.corrcoef(normals[:, 0, 1:].ravel(), normals[:, 0, :-1].ravel())[0, 1]) < 0.01
    assert np.abs(np.corrcoef(normals[:, 0].ravel(), normals[:, 1].ravel())[0, 1]) < 0.01
    assert np.max(np.abs(normals)) > 4.0  # the tail beyond the ziggurat's base is drawn


def _case(seed: int):
    rng = np.random.default_rng(seed)
    steps, count = 25, 48
    noise = (rng.standard_normal((steps, 2, count)) * [[0.4], [2.0]]).astype(np.float32)
    mean = np.column_stack([rng.normal(0.6, 0.3, steps), rng.normal(0.0, 0.5, steps)])
    pose = np.array([rng.uniform(0.5, 10.0), rng.uniform(-0.6, 0.6), rng.normal(0.0, 0.5)])
    wheels, flight = rng.normal(5.0, 2.0, 2), rng.normal([0.5, 0.0], [0.2, 0.5], (2, 2))
    return noise, mean, pose, wheels, flight


def _reference(path, steps: int) -> np.ndarray:
    """The plan's poses ahead as x, y, cos, sin, and a clearance band that varies by step."""
    on_plan = path.sample(1.0 + 0.05 * np.arange(3, 3 + steps))["pose"]
    band = np.linspace(0.0, 0.3, steps)
    return np.column_stack([on_plan[:, :2], np.cos(on_plan[:, 2]), np.sin(on_plan[:, 2]), band])


BACKENDS = [
    pytest.param("numpy", 1e-12, id="numpy"),
    pytest.param("torch", 1e-12, id="torch"),
    pytest.param("jax", 1e-5, id="jax (float32 unless x64)"),
]


@pytest.mark.parametrize(("library", "tolerance"), BACKENDS)
@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize(
    "drive",
    [
        DriveModel(delay=0.1, time_constant=0.1, max_acceleration=30.0),
        DriveModel(delay=0.1),
        DriveModel(time_constant=0.05, gain=0.9, max_acceleration=8.0),
    ],
    ids=["lag and limit", "no lag", "gain and tight limit"],
)
def test_every_backend_scores_the_same_candidates_alike(library, tolerance, seed, drive):
    """One table of cases, every term on (the drive's lag, gain and acceleration limit, every
    wheel limit, obstacles, goal, progress): the compiled cycle against each array library."""
    if library != "numpy":
        LIBRARIES[library].module()  # skips if not installed
    q, path, course = _q(drive)
    noise, mean, pose, wheels, flight = _case(seed)
    reference, grid = _reference(path, len(mean)), course.obstacles.clearance
    costs = np.empty(noise.shape[2])
    state = compiled().in_flight(pose, wheels, flight, q)
    compiled().cycle(mean, q, state, reference, grid, np.uint64(0), False, noise, costs)
    cycle = ArrayCycle(library, 0)
    given_noise = cycle.xp.asarray(noise.astype(float), dtype=cycle.dtype)
    theirs = to_numpy(cycle.costs(q, mean, given_noise, pose, wheels, flight, reference, grid))
    np.testing.assert_allclose(theirs, costs, rtol=tolerance)


@settings(max_examples=25, deadline=None)
@given(
    wheels=st.tuples(*[st.floats(-15, 15)] * 2),
    command=st.tuples(st.floats(-1.5, 1.5), st.floats(-4, 4)),
    tau=st.sampled_from([0.0, 0.03, 0.1, 0.4]),
    limit=st.sampled_from([math.inf, 5.0, 40.0]),
)
def test_the_drive_rolled_out_is_drive_model_step(wheels, command, tau, limit):
    """One period of the rollout's drive is ``DriveModel.step`` on the wheel commands."""
    drive = DriveModel(time_constant=tau, max_acceleration=limit)
    tracker = MPPI(drive=drive, dt=0.05)
    path = plan([(0, 0, 0), (2, 0, 0)], ROBOT, PathLimits(max_velocity=1.0))  # no wheel limit
    q = mppi_settings(tracker, path)
    targets = ROBOT.to_wheel_velocities((command[0], 0.0, command[1])).to_array()
    expected, mean = drive.step(np.array(wheels), targets, 0.05)
    np.testing.assert_allclose(drive_period(q, np.array(wheels), np.array(command)), expected,
                               rtol=1e-12, atol=1e-12)  # fmt: skip
    # The compiled step moves with the mean over the period.
    state = compiled().in_flight(np.zeros(3), np.array(wheels), np.array([command]), q)
    twist = ROBOT.to_twist(dd.WheelVelocities(*mean))
    assert state[6] == pytest.approx(twist.vx, abs=1e-12)
    assert state[7] == pytest.approx(twist.omega, abs=1e-12)
    pose = dd.integrate.step(dd.Pose(0, 0, 0), twist, 0.05, method="exact")
    np.testing.assert_allclose(state[:2], [pose.x, pose.y], atol=1e-12)
    np.testing.assert_allclose(state[2:4], [math.cos(pose.theta), math.sin(pose.theta)],
                               atol=1e-12)  # fmt: skip


@pytest.mark.slow
@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_it_follows_a_plan_through_a_known_delay_and_lag_within_the_wheels_limit(backend):
    """Planned at 10 rad/s a wheel, the wheels' limit 12 the controller keeps (room to catch
    up); 0.1 s of delay and 0.1 s of lag rolled out: within 10 mm on average, 40 mm at most."""
    limits = PathLimits(max_velocity=1.0, max_acceleration=1.0, max_wheel_velocity=10.0)
    path = plan([(0, 0, 0), (3, 1, 0.5), (5, 3, 1.5)], ROBOT, limits)
    drive = DriveModel(delay=0.1, time_constant=0.1)
    tracker = MPPI(
        drive=drive,
        limits=WheelLimits(max_velocity=12.0),
        backend=backend,
        sampling=MPPISampling(seed=1),
    )
    result = follow(path, tracker, dt=0.05, drive=drive)
    cross = np.abs(result.errors().cross_track)
    assert cross.mean() < 0.010
    assert cross.max() < 0.040
    assert cross.max() < 0.040
    assert np.abs(result.wheel_velocities).max() <= 12.0


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(4))
def test_it_goes_around_the_clutter_of_a_corridor_without_touching(seed):
    """A straight plan through a corridor cluttered with circles (a way through exists),
    0.1 s of delay and 0.1 s of lag: no touch, the goal reached within 1.3 times the plan."""
    course = cluttered_corridor(np.random.default_rng(seed), footprint=FOOTPRINT)
    path = plan([course.start, course.goal], ROBOT, LIMITS)
    assert course.touches(path.poses, FOOTPRINT).any()  # the plan alone would collide
    drive = DriveModel(delay=0.1, time_constant=0.1)
    tracker = MPPI(
        drive=drive,
        sampling=MPPISampling(seed=seed),
        avoid=Avoidance(course.obstacles, footprint=FOOTPRINT),
    )
    result = follow(
        path, tracker, dt=0.05, drive=drive, settings=FollowSettings(settle=0.5 * path.duration)
    )
    assert not course.touches(result.poses[0], FOOTPRINT).any()
    reached = np.flatnonzero(np.hypot(*(result.poses[0, :, :2] - course.goal[:2]).T) < 0.1)
    assert len(reached)
    assert result.times[reached[0]] - result.times[0] <= 1.3 * path.duration


def test_a_batch_of_robots_each_gets_its_own_sequence_and_the_count_is_kept() -> None:
    path = plan([(0, 0, 0), (2, 0, 0)], ROBOT, PathLimits(max_velocity=1, max_acceleration=1))
    tracker = MPPI(sampling=MPPISampling(horizon=0.5, seed=0))
    poses = np.array([[0.0, 0.0, 0.0], [0.0, 0.3, 0.0]])
    turns = np.array([tracker.command(path, 0.05 * k, poses)[:, 1] for k in range(10)])
    assert turns.shape == (10, 2)
    assert turns[:, 1].mean() < turns[:, 0].mean() - 0.1  # left of the path: turns right
    with pytest.raises(ValueError, match="expected 2 poses as before, got 1"):
        tracker.command(path, 0.05, np.zeros((1, 3)))
    tracker.reset()
    assert tracker.command(path, 0.0, np.zeros((1, 3))).shape == (1, 2)


@pytest.mark.parametrize("library", ["torch", "jax"])
def test_an_array_library_runs_the_controller(library):
    """On an array library's own generator: a few cycles steer a robot left of the path back,
    forwards turning right or backwards turning left (v omega < 0 brings y down)."""
    LIBRARIES[library].module()
    path = plan([(0, 0, 0), (2, 0, 0)], ROBOT, PathLimits(max_velocity=1, max_acceleration=1))
    tracker = MPPI(backend=library, sampling=MPPISampling(horizon=0.5, samples=256, seed=0))
    sent = [tracker.command(path, 0.05 * k, np.array([[0.0, 0.3, 0.0]]))[0] for k in range(6)]
    assert np.all(np.isfinite(sent))
    assert np.mean([v * omega for v, omega in sent]) < -0.05


def test_guide_keeps_a_clear_plan_and_routes_a_blocked_one_around():
    clear = plan([(0, 0, 0), (4, 0, 0)], ROBOT, LIMITS)
    far = Obstacles.from_circles([(2.0, 3.0)], [0.5])
    assert guide(clear, far, FOOTPRINT) is clear
    blocking = Obstacles.from_circles([(2.0, 0.05)], [0.5], resolution=0.02)
    routed = guide(clear, blocking, FOOTPRINT, inflation=0.2)
    assert blocking.clearance_at(routed.poses[:, :2]).min() > FOOTPRINT
    np.testing.assert_allclose(routed.poses[[0, -1], :2], clear.poses[[0, -1], :2], atol=1e-9)
    # Through two corners alone the spline bulged 0.5 m into a circle: points are added.
    course = cluttered_corridor(np.random.default_rng(762), footprint=FOOTPRINT)
    straight = plan([course.start, course.goal], ROBOT, LIMITS)
    assert course.clearance(guide(straight, course.obstacles, FOOTPRINT).poses[:, :2]).min() > (
        FOOTPRINT
    )
    wall = [(2.0, y) for y in np.arange(-3, 3.1, 0.5)]
    walled = Obstacles.from_circles(wall, [0.4], bounds=(-1.0, -3.0, 5.0, 3.0))
    with pytest.raises(ValueError, match="no way around the obstacles"):
        guide(clear, walled, FOOTPRINT)


def test_circles_give_the_exact_clearance_at_the_nodes():
    field = Obstacles.from_circles([(1.0, 1.0), (3.0, 0.0)], [0.5, 0.25], resolution=0.1)
    rows, cols = field.clearance.shape
    i, j = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    x, y = field.origin[0] + 0.1 * j, field.origin[1] + 0.1 * i
    exact = np.minimum(np.hypot(x - 1, y - 1) - 0.5, np.hypot(x - 3, y) - 0.25)
    np.testing.assert_allclose(field.clearance, exact, atol=1e-12)
    # Between nodes, bilinear: the node 5 cm below the first circle's centre, then half way.
    assert field.clearance_at([1.0, 0.95]) == pytest.approx(-0.45, abs=1e-9)
    assert field.clearance_at([1.0, 1.0]) == pytest.approx(-0.45, abs=1e-9)


def _write_map(folder, pixels: np.ndarray, **meta) -> object:
    from PIL import Image

    Image.fromarray(pixels.astype(np.uint8)).save(folder / "map.pgm")
    fields = {"image": "map.pgm", "resolution": 0.1, "origin": [-1.0, -2.0, 0.0],
              "negate": 0, "occupied_thresh": 0.65, "free_thresh": 0.196} | meta  # fmt: skip
    lines = [f"{key}: {value}" for key, value in fields.items() if value is not None]
    (folder / "map.yaml").write_text("\n".join(lines) + "\n")
    return folder / "map.yaml"


def test_a_ros_map_is_read_as_map_servers_read_it(tmp_path):
    """254 free, 0 occupied, 205 unknown (map_saver's values); the image's top row is the
    highest y; unknown counts as occupied; negate reads the shades the other way round."""
    pixels = np.full((20, 30), 254)
    pixels[0, 0] = 0  # top left: the map's highest y, lowest x
    pixels[19, 29] = 205  # bottom right: unknown
    obstacles = read_map(_write_map(tmp_path, pixels))
    rows, cols = obstacles.clearance.shape
    assert (rows, cols) == (20, 30)
    assert obstacles.origin == pytest.approx((-0.95, -1.95))  # cell (0, 0)'s centre
    top_left = (-1.0 + 0.05, -2.0 + 20 * 0.1 - 0.05)
    bottom_right = (-1.0 + 30 * 0.1 - 0.05, -2.0 + 0.05)
    assert obstacles.clearance_at(top_left) < 0
    assert obstacles.clearance_at(bottom_right) < 0
    assert obstacles.clearance_at((0.5, -1.0)) > 0.5
    negated = read_map(_write_map(tmp_path, 255 - pixels, negate=1))
    np.testing.assert_allclose(negated.clearance, obstacles.clearance)


@pytest.mark.parametrize(
    ("meta", "message"),
    [
        ({"origin": None}, "the map's origin is missing"),
        ({"resolution": None}, "the map's resolution is missing"),
        ({"origin": [0.0, 0.0, 0.3]}, "origin yaw 0.3 is not 0"),
        ({"resolution": -0.1}, "resolution must be"),
        ({"image": "nothing.png"}, "could not be read"),
    ],
)
def test_a_map_missing_what_it_needs_is_refused_by_name(tmp_path, meta, message):
    path = _write_map(tmp_path, np.full((5, 5), 254), **meta)
    with pytest.raises(ValueError, match=message):
        read_map(path)


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: MPPICosts(cross_track=-1.0), "cost weight cross_track must be >= 0"),
        (lambda: MPPICosts(rate=math.nan), "cost weight rate must be finite"),
        (lambda: MPPICosts(collision=math.inf), "cost weight collision must be finite"),
        (lambda: MPPI(sampling=MPPISampling(samples=0)), "samples must be"),
        (lambda: MPPI(delay=0.07, dt=0.05), "delay must be a whole number of dt"),
        (lambda: MPPI(sampling=MPPISampling(sigma=(0.1, 0.0))), "sigma must be"),
        (
            lambda: MPPI(sampling=MPPISampling(samples=10**6, horizon=500.0)),
            "MPPI's samples x horizon",
        ),
        (lambda: MPPI(backend="cupy"), "backend must be one of"),
        (
            lambda: MPPISampling(horizon=20),
            r"MPPISampling\.horizon is in seconds; 20 is an int, as its count of steps was "
            r"before: give seconds as a float \(20 steps at 0\.05 s: 1\)",
        ),
        (lambda: MPPISampling(smoothing=-0.1), r"MPPISampling\.smoothing \(s\) must be > 0"),
        (lambda: WheelLimits(max_voltage=12.0), "max_voltage and feedforward go together"),
        (
            lambda: WheelLimits(max_voltage=0.4, feedforward=FEEDFORWARD),
            "max_voltage 0.4 V does not exceed the left wheel's kS 0.5 V",
        ),
        (lambda: WheelLimits(max_velocity=-1.0), r"WheelLimits\.max_velocity must be > 0"),
        (lambda: MPPI(limits=PathLimits(max_velocity=1.0)), "limits must be WheelLimits"),
        (
            lambda: Avoidance(Obstacles(np.ones((3, 3)), (0.0, 0.0), 0.1), footprint=-0.1),
            r"Avoidance\.footprint must be >= 0",
        ),
        (lambda: MPPI(avoid="map.yaml"), "avoid must be an Avoidance, got str"),
        (lambda: Arrival(tolerance=0.0), r"Arrival\.tolerance must be > 0"),
        (lambda: Arrival(stall=math.nan), r"Arrival\.stall \(s\) must be"),
        (lambda: MPPI(arrival=0.05), "settings must be an Arrival, got float"),
        (lambda: MPPI(sampling={"samples": 10}), "settings must be an MPPISampling, got dict"),
        (lambda: Obstacles(np.zeros((3, 3)), (0.0,), 0.1), "origin must be a finite"),
        (lambda: Obstacles(np.zeros((3, 3)), (0.0, 0.0), 0.0), "resolution must be"),
    ],
)
def test_bad_settings_are_refused_by_name(make, message):
    with pytest.raises((ValueError, TypeError), match=message):
        make()


def test_a_start_inside_an_obstacle_is_refused_and_the_controller_is_unchanged():
    path = plan([(0, 0, 0), (4, 0, 0)], ROBOT, LIMITS)
    obstacles = Obstacles.from_circles([(0.3, -1.8)], [0.2])
    tracker = MPPI(sampling=MPPISampling(seed=0), avoid=Avoidance(obstacles, footprint=FOOTPRINT))
    with pytest.raises(ValueError, match=r"robot 1 starts inside an obstacle: at \(0\.100"):
        tracker.command(path, 0.0, np.array([[0.0, 0.5, 0.0], [0.1, -2.0, 0.0]]))
    assert tracker._mean.shape == (0, 30, 2)  # nothing was started (30 steps among obstacles)
    assert tracker.command(path, 0.0, np.array([[0.0, 0.5, 0.0]])).shape == (1, 2)


def test_nav2_parameters_carry_what_corresponds():
    """The sampling, the horizon with the steps in flight, and the limits from the wheels';
    no obstacle critic without obstacles; the acceleration limits where the wheels have one."""
    import yaml

    from diffdrive.export.nav2_mppi import nav2_mppi_parameters, render_nav2_mppi

    tracker = MPPI(
        dt=0.04,
        delay=0.08,
        limits=WheelLimits(max_acceleration=30.0),
        sampling=MPPISampling(samples=2000, horizon=2.0, sigma=(0.2, 0.5)),
    )
    limits = PathLimits(max_wheel_velocity=12.0)
    figures = nav2_mppi_parameters(tracker, ROBOT, limits)
    assert (figures["batch_size"], figures["time_steps"], figures["model_dt"]) == (2000, 52, 0.04)
    assert (figures["vx_std"], figures["wz_std"]) == (0.2, 0.5)
    assert figures["vx_max"] == pytest.approx(1.2)  # both wheels at 12 rad/s
    assert figures["wz_max"] == pytest.approx(4.0)  # a turn in place at 12 rad/s
    assert figures["ax_max"] == pytest.approx(3.0)
    assert figures["az_max"] == pytest.approx(10.0)
    assert "ObstaclesCritic" not in figures["critics"]
    text = render_nav2_mppi(tracker, ROBOT, limits)
    read = yaml.safe_load(text)["controller_server"]["ros__parameters"]["FollowPath"]
    assert read == figures
    with pytest.raises(ValueError, match="need a wheel limit"):
        nav2_mppi_parameters(MPPI(), ROBOT, PathLimits(max_velocity=1.0))


def test_sampled_shows_candidates_and_leaves_the_controller_as_it_was():
    path = plan([(0, 0, 0), (2, 0, 0)], ROBOT, LIMITS)
    tracker = MPPI(sampling=MPPISampling(horizon=0.5, seed=3))
    with pytest.raises(ValueError, match="call command first"):
        tracker.sampled(path, np.zeros(3))
    tracker.command(path, 0.0, np.zeros((1, 3)))
    twin = MPPI(sampling=MPPISampling(horizon=0.5, seed=3))
    twin.command(path, 0.0, np.zeros((1, 3)))
    candidates = tracker.sampled(path, np.zeros(3), count=5)
    assert candidates.shape == (5, 10, 2)
    np.testing.assert_array_equal(tracker.command(path, 0.05, np.zeros((1, 3))),
                                  twin.command(path, 0.05, np.zeros((1, 3))))  # fmt: skip


def test_without_the_guide_the_plan_is_followed_as_given():
    course = cluttered_corridor(np.random.default_rng(1), footprint=FOOTPRINT)
    path = plan([course.start, course.goal], ROBOT, LIMITS)
    guided = MPPI(avoid=Avoidance(course.obstacles, footprint=FOOTPRINT))
    plain = MPPI(avoid=Avoidance(course.obstacles, footprint=FOOTPRINT, around=False))
    assert plain._guided(path) is path
    assert guided._guided(path) is not path
    assert guided._guided(path) is guided._guided(path)  # made once


@pytest.mark.parametrize("backend", ["numpy", "numba"])
@pytest.mark.parametrize(
    ("time", "shift", "costs", "message"),
    [
        (math.nan, 0.0, None, "t must be finite"),
        (0.1, 1e200, None, "its pose is 1e\\+200 m from the plan"),
        (0.1, 2.0, MPPICosts(cross_track=1e308), "the largest cost weight is 1e\\+308"),
    ],
    ids=["a NaN time", "a pose 1e200 m off", "a weight of 1e308"],
)
def test_a_refused_cycle_changes_nothing(backend, time, shift, costs, message):
    """One cycle given a NaN time, a pose 1e200 m off or a weight of 1e308 made a NaN command
    without an error, and the NaN time every later command NaN: each is refused by name, and
    the next cycle commands what a controller that never saw it commands."""
    if backend == "numba":
        compiled()
    planned = plan(np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 1.0], [3.0, 1.0]]), ROBOT, LIMITS)
    sampling = MPPISampling(horizon=0.5, samples=128, seed=3)
    made = [MPPI(dt=0.05, backend=backend, sampling=sampling, costs=costs) for _ in range(2)]
    start = planned.poses[:1] + np.array([[0.05, 0.02, 0.0]])
    for tracker in made:
        tracker.command(planned, 0.0, start)
    bad = start + np.array([[0.0, shift, 0.0]])
    with pytest.raises(ValueError, match=message):
        made[0].command(planned, time, bad)
    after = [tracker.command(planned, 0.05, start) for tracker in made]
    assert np.all(np.isfinite(after[0]))
    np.testing.assert_array_equal(after[0], after[1])


def _threads_of_cycles(monkeypatch, kernel) -> list[int]:
    """The threads each compiled cycle runs on from now, as the test goes on."""
    import numba

    seen: list[int] = []
    cycle = kernel.cycle

    def spy(*args):
        seen.append(numba.get_num_threads())
        return cycle(*args)

    monkeypatch.setattr(kernel, "cycle", spy)
    return seen


@pytest.mark.parametrize(("running", "free"), [(1, 2), (2, 1), (9, 1)])
def test_the_compiled_cycle_runs_on_the_cores_no_other_task_holds(monkeypatch, running, free):
    """A cycle's blocks wait for the slowest thread: with the other core busy, 2,048 x 100
    took 95 ms on two threads and 29 ms on one. It counts the tasks running now as
    ``simulate``'s kernel does (this one among them) and leaves numba's own count as it
    was."""
    import numba

    from diffdrive.backends import simulate_kernel

    kernel = compiled()
    monkeypatch.setattr(simulate_kernel, "threads", lambda: 2)
    monkeypatch.setattr(simulate_kernel, "_running_tasks", lambda: running)
    monkeypatch.setattr(simulate_kernel, "_own_running", lambda: 1)
    expected = min(free, numba.config.NUMBA_NUM_THREADS)
    assert kernel.free_threads() == expected
    seen = _threads_of_cycles(monkeypatch, kernel)
    before = numba.get_num_threads()
    path = plan([(0, 0, 0), (2, 0, 0)], ROBOT, LIMITS)
    MPPI(backend="numba", sampling=MPPISampling(horizon=0.25, samples=64, seed=0)).command(
        path, 0.0, np.zeros((1, 3))
    )
    assert seen == [expected]
    assert numba.get_num_threads() == before


def test_the_free_cores_are_counted_again_only_after_recount_seconds(monkeypatch):
    """Just after a cycle the count takes 0.1 to 0.4 ms, which had made a cycle on a busy
    machine slower than one forced onto one thread: a controller counts at its first cycle,
    keeps the count for ``RECOUNT`` s, then counts again; a new controller counts anew."""
    import numba

    from diffdrive.control import mppi as module

    kernel = compiled()
    pool = numba.config.NUMBA_NUM_THREADS
    now, counts = [100.0], [1, min(2, pool), 1]
    asked = []

    def count():
        asked.append(now[0])
        return counts[len(asked) - 1]

    class Clock:
        @staticmethod
        def monotonic():
            return now[0]

    monkeypatch.setattr(kernel, "free_threads", count)
    monkeypatch.setattr(module, "time", Clock)
    seen = _threads_of_cycles(monkeypatch, kernel)
    path = plan([(0, 0, 0), (2, 0, 0)], ROBOT, LIMITS)
    tracker = MPPI(backend="numba", sampling=MPPISampling(horizon=0.25, samples=64, seed=0))
    times = [100.0 + share * module.RECOUNT for share in (0.0, 0.5, 0.9, 1.1)]
    for step, now[0] in enumerate(times):
        tracker.command(path, 0.05 * step, np.zeros((1, 3)))
    assert asked == [times[0], times[3]]
    assert seen == [1, 1, 1, min(2, pool)]
    MPPI(backend="numba", sampling=MPPISampling(horizon=0.25, samples=64, seed=0)).command(
        path, 0.0, np.zeros((1, 3))
    )
    assert len(asked) == 3


@pytest.mark.parametrize("dt", [0.02, 0.05, 0.1])
def test_the_horizon_and_smoothing_are_times_converted_at_the_period(dt):
    """The same settings at 20, 50 and 100 ms: the horizon (by default the delay, three lag
    time constants and a stop from full speed, at least 1 s) and the smoothing span the same
    time, however many steps that is."""
    drive = DriveModel(delay=0.1, time_constant=0.1)
    plain = MPPI(dt=dt, drive=drive)
    assert plain.horizon == round(1.0 / dt)
    assert plain.smoothing == max(1, round(0.25 / dt))
    wheels = WheelLimits(max_velocity=14.0, max_acceleration=10.0)
    limited = MPPI(dt=dt, drive=drive, limits=wheels)
    assert limited.horizon * dt == pytest.approx(0.1 + 0.3 + 1.4, abs=dt / 2)
    given = MPPI(dt=dt, drive=drive, sampling=MPPISampling(horizon=2.0, smoothing=0.1))
    assert given.horizon * dt == pytest.approx(2.0)
    assert given.smoothing == max(1, round(0.1 / dt))


def _limited(tau: float, velocity, acceleration, voltage):
    """The cycle's numbers for wheels limited as given (voltage through FEEDFORWARD)."""
    limits = WheelLimits(velocity, acceleration, voltage, None if voltage is None else FEEDFORWARD)
    tracker = MPPI(drive=DriveModel(time_constant=tau), dt=0.02, limits=limits)
    return mppi_settings(tracker, plan([(0, 0, 0), (2, 0, 0)], ROBOT, PathLimits(1.0)))


def _within(q, before: np.ndarray, after: np.ndarray) -> None:
    """Each wheel's velocity, acceleration and voltage over the period within the limits."""
    acceleration = (after - before) / q.dt
    assert np.all(np.abs(after) <= q.max_wheel_velocity * (1 + 1e-9))
    assert np.all(np.abs(acceleration) <= q.max_wheel_acceleration * (1 + 1e-9))
    moving = np.where(after != 0.0, after, before)  # friction opposes the motion
    volts = FEEDFORWARD.ks * np.sign(moving) + FEEDFORWARD.kv * after
    volts += FEEDFORWARD.ka * acceleration
    assert np.all(np.abs(volts) <= q.max_voltage * (1 + 1e-9) + 1e-9)


@settings(max_examples=60, deadline=None)
@given(
    commands=st.lists(st.tuples(st.floats(-3, 3), st.floats(-12, 12)), min_size=1, max_size=40),
    tau=st.sampled_from([0.0, 0.02, 0.1]),
    velocity=st.sampled_from([14.0, 6.0, None]),
    acceleration=st.sampled_from([20.0, 200.0, None]),
    voltage=st.sampled_from([12.0, 4.0, None]),
)
def test_no_rollout_leaves_the_drives_limits(commands, tau, velocity, acceleration, voltage):
    """Any sequence of commands, rolled out from rest as the cycle does (compiled and in
    arrays) and as the controller sends them (``feasible_commands``), keeps every wheel within
    its velocity, acceleration and voltage limits in every period."""
    q = _limited(tau, velocity, acceleration, voltage)
    sent = feasible_commands(q, np.zeros(2), np.array(commands))
    before = state = np.zeros(2)
    for command, raw in zip(sent, commands, strict=True):
        after = drive_period(q, before, command)  # as the drive answers what was sent
        _within(q, before, after)
        # The compiled rollout of the raw candidate ends where the arrays' does.
        state = compiled().in_flight(np.zeros(3), before, np.array([raw]), q)[4:6]
        assert np.allclose(state, drive_period(q, before, np.array(raw)), atol=1e-9)
        _within(q, before, state)
        before = after
    # Commands within the limits already are sent as given.
    again = feasible_commands(q, np.zeros(2), sent)
    np.testing.assert_allclose(again, sent, rtol=1e-9, atol=1e-9)


def test_the_command_does_not_depend_on_how_many_threads_the_cycle_had(monkeypatch):
    """The update's weights are summed in one thread: the same seed, the same command on one
    thread as on every one."""
    kernel = compiled()
    path = plan([(0, 0, 0), (3, 1, 0.5)], ROBOT, LIMITS)
    sent = []
    for threads in (1, kernel.free_threads()):
        monkeypatch.setattr(kernel, "free_threads", lambda threads=threads: threads)
        tracker = MPPI(backend="numba", sampling=MPPISampling(samples=4096, seed=2))
        sent.append(tracker.command(path, 0.0, np.array([[0.05, -0.02, 0.1]])))
    np.testing.assert_array_equal(sent[0], sent[1])


@pytest.mark.slow
@pytest.mark.parametrize("period", [0.02, 0.05, 0.1])
def test_the_same_defaults_track_within_the_limits_at_three_periods(period):
    """The issue's robot (0.075 m wheels, 0.38 m track; 14 rad/s, 20 rad/s^2 and 12 V through
    a feedforward) on a path planned at 90 % of those limits, 0.1 s of delay and lag known:
    with the same defaults at 20, 50 and 100 ms, no period with a wheel past a limit by over
    1 %, the cross-track error 10 mm on average and 40 mm at most, and the robot within 0.05 m
    of the plan's end 1 s after it. (At 20 ms it had been 183 mm on average, a wheel's
    acceleration 1.9 times its limit.)"""
    robot = dd.DiffDrive(wheel_radius=0.075, track_width=0.38)
    limits = WheelLimits(14.0, 20.0, 12.0, FEEDFORWARD)
    planned = PathLimits(
        max_wheel_velocity=12.6, max_wheel_acceleration=18.0, max_voltage=10.8,
        feedforward=FEEDFORWARD,
    )  # fmt: skip
    path = plan([(0, 0, 0), (2.5, 1.0, 0.6), (4.0, 3.0, 1.4)], robot, planned)
    drive = DriveModel(delay=0.1, time_constant=0.1)
    tracker = MPPI(dt=period, drive=drive, limits=limits, sampling=MPPISampling(seed=1))
    result = follow(path, tracker, dt=period, drive=drive)
    wheels = result.wheel_velocities[0]
    acceleration = np.diff(wheels, axis=0) / period
    moving = np.where(wheels[1:] != 0.0, wheels[1:], wheels[:-1])
    volts = FEEDFORWARD.ks * np.sign(moving) + FEEDFORWARD.kv * wheels[1:]
    volts += FEEDFORWARD.ka * acceleration
    assert np.abs(wheels).max() <= 14.0 * 1.01
    assert np.abs(acceleration).max() <= 20.0 * 1.01
    assert np.abs(volts).max() <= 12.0 * 1.01
    cross = np.abs(result.errors().cross_track)
    assert cross.mean() < 0.010
    assert cross.max() < 0.040
    assert np.hypot(*(result.poses[0, -1, :2] - path.poses[-1, :2])) < 0.05


def _run_among(circles, end: float, around: bool = True):
    """A straight plan from the origin to ``(end, 0)`` among ``circles`` (``(x, y, radius)``),
    followed by MPPI through a known delay and lag; the plan, controller, run and obstacles."""
    centres, radii = [c[:2] for c in circles], [c[2] for c in circles]
    obstacles = Obstacles.from_circles(centres, radii, bounds=(-1, -3, 6, 3))
    path = plan([(0, 0, 0), (end, 0, 0)], ROBOT, LIMITS)
    drive = DriveModel(delay=0.1, time_constant=0.1)
    tracker = MPPI(
        drive=drive,
        sampling=MPPISampling(seed=1),
        avoid=Avoidance(obstacles, footprint=FOOTPRINT, around=around),
    )
    run = follow(path, tracker, dt=0.05, drive=drive, settings=FollowSettings(settle=8.0))
    return path, tracker, run, obstacles


@pytest.mark.parametrize("gap", [0.1, 0.2])
def test_a_goal_inside_the_clearance_band_is_reached(gap):
    """A goal 0.1 or 0.2 m from a wall, inside the 0.3 m band: the band is narrowed to the
    plan's own gap, so the robot arrives (it had stopped 193 and 96 mm short, held off by the
    band) without touching."""
    wall = [(3.5, y, 0.5) for y in np.linspace(-2.0, 2.0, 9)]
    path, tracker, run, obstacles = _run_among(wall, 3.0 - FOOTPRINT - gap)
    end = np.hypot(*(run.poses[0, -1, :2] - path.poses[-1, :2]))
    assert end < 0.02
    assert obstacles.clearance_at(run.poses[0, :, :2]).min() > FOOTPRINT
    assert tracker.stalls == []


@pytest.mark.parametrize("block", [2.6, 3.2])
def test_a_stall_near_the_goal_is_found_and_a_way_around_followed(block):
    """The plan followed as given (no guide) through a circle 0.8 to 1.4 m before the goal:
    the robot stops in front of it (it had stayed 2.3 and 1.7 m from the goal). The stall is
    found after a second standing, a way around from where it stands is made, and the robot
    arrives within the tolerance without touching."""
    path, tracker, run, obstacles = _run_among([(block, 0.0, 0.3)], 4.0, around=False)
    (stall,) = tracker.stalls
    assert stall.detour
    assert stall.robot == 0
    assert 1.5 < stall.distance < 2.5
    found = int(np.searchsorted(run.times, stall.t - 1e-9))
    second = run.poses[0, found - 20 : found + 1, :2]  # the second before it was found
    assert np.hypot(*(second - second[-1]).T).max() < 0.5 * Arrival().tolerance  # 2 radii
    end = np.hypot(*(run.poses[0, -1, :2] - path.poses[-1, :2]))
    assert end < Arrival().tolerance
    assert obstacles.clearance_at(run.poses[0, :, :2]).min() > FOOTPRINT


def test_a_stall_with_no_way_out_is_kept_with_its_reason():
    """A goal walled in: the stall is found and kept with the guide's reason, not hidden."""
    ring = [(2.0 + 0.9 * np.cos(a), 0.9 * np.sin(a)) for a in np.linspace(0, 2 * np.pi, 24)]
    obstacles = Obstacles.from_circles(ring, 0.25, bounds=(-1, -2, 4, 2))
    path = plan([(0, 0, 0), (2.0, 0, 0)], ROBOT, LIMITS)
    drive = DriveModel(delay=0.1, time_constant=0.1)
    tracker = MPPI(
        drive=drive,
        sampling=MPPISampling(seed=1),
        avoid=Avoidance(obstacles, footprint=0.2, around=False),
    )
    follow(path, tracker, dt=0.05, drive=drive, settings=FollowSettings(settle=3.0))
    assert tracker.stalls
    assert not any(stall.detour for stall in tracker.stalls)
    assert "no way around the obstacles" in tracker.stalls[0].why


def test_a_plan_that_creeps_away_is_not_a_stall():
    """WPILib's trajectory starts at 0.1 m/s^2: in its first second the plan moves 5 cm and the
    robot, behind it, less than a quarter of the tolerance. That is following, not a stall
    (it had been taken for one every second, and the way made each time cost 1.4 m of
    cross-track error on average)."""
    path = plan([(0, 0, 0), (0.5, 0, 0)], ROBOT, PathLimits(max_velocity=1, max_acceleration=0.02))
    drive = DriveModel(delay=0.1, time_constant=0.1)
    tracker = MPPI(drive=drive, sampling=MPPISampling(samples=256, seed=1))
    run = follow(path, tracker, dt=0.05, drive=drive)
    assert tracker.stalls == []
    assert np.abs(run.errors().cross_track).max() < 0.005
    assert np.hypot(*(run.poses[0, -1, :2] - path.poses[-1, :2])) < Arrival().tolerance
