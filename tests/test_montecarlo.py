"""Monte Carlo without paths: its statistics against Odometry's propagated covariance (an
independent oracle: the same error model, linearised), its seeding, and its refusals."""

import numpy as np
import pytest

import diffdrive as dd
from diffdrive.montecarlo import Moments, monte_carlo

ROBOT = dd.DiffDrive(0.05, 0.3)
DT = 0.02
T = np.arange(400) * DT
WHEELS = np.stack([8 + 3 * np.sin(T), 8 - 3 * np.sin(0.7 * T)], axis=-1)


@pytest.mark.slow
@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_the_spread_matches_odometry_covariance(backend):
    result = monte_carlo(
        ROBOT, WHEELS, DT, 20_000, wheel_noise=(1e-4, 2e-4), seed=1, backend=backend
    )
    odometry = dd.Odometry(ROBOT, wheel_noise=(1e-4, 2e-4))
    poses, covariances = odometry.update_arrays("increments", *(WHEELS * DT).T, covariance=True)
    # 20,000 robots: a variance is known to about sqrt(2/N) = 1 %; the model is linearised.
    # Compared scaled by the deviations, so that a near-zero correlation counts absolutely.
    for step in (100, 250, 400):  # the pose after that many steps
        want = covariances[step - 1]
        scale = np.sqrt(np.outer(np.diag(want), np.diag(want)))
        np.testing.assert_allclose(result.covariance[step] / scale, want / scale, atol=0.04)
    # The mean leaves the nominal path by second-order terms of the heading's noise
    # (E[cos(theta + e)] = cos(theta) exp(-var(e)/2)): a tenth of the spread here.
    spread = np.sqrt(np.diag(covariances[-1]))
    assert np.all(np.abs(result.mean[-1] - poses[-1]) < 0.15 * spread)
    assert result.final.shape == (20_000, 3)
    np.testing.assert_allclose(result.final.mean(axis=0), result.mean[-1], atol=1e-12)
    q = result.quantiles([0.05, 0.5, 0.95])
    assert q.shape == (3, 3)
    assert np.all(q[0] < q[1])
    assert np.all(q[1] < q[2])


def test_without_noise_every_robot_drives_the_nominal_path():
    result = monte_carlo(ROBOT, WHEELS, DT, 50, initial_pose=(1.0, 2.0, 0.5), seed=0)
    path = dd.simulate(ROBOT, WHEELS, dt=DT, initial_pose=(1.0, 2.0, 0.5)).poses
    np.testing.assert_allclose(result.mean, path, atol=1e-12)
    np.testing.assert_allclose(result.final, np.tile(path[-1], (50, 1)), atol=1e-12)
    np.testing.assert_allclose(result.covariance, 0.0, atol=1e-20)


@pytest.mark.slow
def test_a_geometry_error_spreads_the_heading_as_its_formula_says():
    # Straight at 0.4 m/s for 8 s: a right-left radius difference e turns the robot by
    # (e_r - e_l) * r * phi / track; with sigma 1 % on each, the heading's deviation is
    # sqrt(2) * 0.01 * (distance / track).
    straight = np.tile([8.0, 8.0], (400, 1))
    result = monte_carlo(ROBOT, straight, DT, 40_000, geometry_sigma=(0.01, 0.01, 0.0), seed=2)
    want = np.sqrt(2) * 0.01 * (0.4 * 8.0 / 0.3)
    assert np.sqrt(result.covariance[-1, 2, 2]) == pytest.approx(want, rel=0.03)


def test_the_numbers_depend_on_the_seed_and_chunk_not_on_the_threads():
    one = monte_carlo(ROBOT, WHEELS, DT, 1000, wheel_noise=(1e-4, 0.0), seed=5, chunk=300)
    two = monte_carlo(
        ROBOT, WHEELS, DT, 1000, wheel_noise=(1e-4, 0.0), seed=5, chunk=300, threads=2
    )
    np.testing.assert_array_equal(one.final, two.final)
    np.testing.assert_allclose(one.covariance, two.covariance, rtol=1e-9, atol=1e-20)
    other = monte_carlo(ROBOT, WHEELS, DT, 1000, wheel_noise=(1e-4, 0.0), seed=6, chunk=300)
    assert not np.array_equal(one.final, other.final)
    unseeded = [
        monte_carlo(ROBOT, WHEELS, DT, 10, wheel_noise=(1e-4, 0.0), chunk=3) for _ in range(2)
    ]
    assert not np.array_equal(unseeded[0].final, unseeded[1].final)


def test_merged_moments_equal_those_of_all_the_data():
    rng = np.random.default_rng(0)
    data = rng.normal(size=(3, 100, 4, 3))  # three parts of 100 robots, 4 steps

    def moments(part):
        deviation = part - part.mean(axis=0)
        return Moments(
            len(part), part.mean(axis=0), np.einsum("nti,ntj->tij", deviation, deviation)
        )

    merged = Moments.combine([moments(part) for part in data])
    every = moments(data.reshape(300, 4, 3))
    np.testing.assert_allclose(merged.mean, every.mean, atol=1e-15)
    np.testing.assert_allclose(merged.m2, every.m2, rtol=1e-12)


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"robots": 0}, "robots must be a whole number from 1"),
        ({"robots": 2.5}, "robots must be a whole number"),
        ({"wheel_noise": (-1e-4, 0.0)}, "wheel noise left must be a number >= 0"),
        ({"geometry_sigma": (0.01, 0.01)}, "geometry_sigma"),
        ({"dt": 0.0}, "dt must be > 0"),
        ({"wheel_velocities": np.ones((2, 5, 2))}, r"one history \(T, 2\)"),
        ({"wheel_velocities": np.full((5, 2), np.nan)}, "must be finite"),
        ({"initial_pose": (0.0, 0.0)}, "initial_pose"),
        ({"method": "midpoint"}, "method must be one of"),
        ({"backend": "gpu"}, "backend must be one of"),
    ],
)
def test_bad_input_is_refused_with_its_name(changes, message):
    arguments = {"wheel_velocities": WHEELS, "dt": DT, "robots": 10} | changes
    robots = arguments.pop("robots")
    with pytest.raises(ValueError, match=message):
        monte_carlo(
            ROBOT, arguments.pop("wheel_velocities"), arguments.pop("dt"), robots, **arguments
        )


def test_seeds_past_two_to_the_53_are_kept_exactly():
    """2**53 and 2**53 + 1 went through a float and gave the same robots."""
    runs = [
        monte_carlo(ROBOT, WHEELS, DT, 20, wheel_noise=(1e-4, 0.0), seed=2**53 + k) for k in (0, 1)
    ]
    assert not np.array_equal(runs[0].final, runs[1].final)
    again = monte_carlo(ROBOT, WHEELS, DT, 20, wheel_noise=(1e-4, 0.0), seed=np.uint64(2**53 + 1))
    np.testing.assert_array_equal(again.final, runs[1].final)
    with pytest.raises(ValueError, match="seed must be a whole number from 0"):
        monte_carlo(ROBOT, WHEELS, DT, 20, seed=-1)


@pytest.mark.parametrize("backend", ["numpy", "numba"])
@pytest.mark.parametrize(
    ("wheels", "dt", "options", "message"),
    [
        (np.full((3, 2), 1e300), 1e10, {}, "the wheels' travel"),
        (np.full((4, 2), 1e307), 10.0, {}, "the wheels' travel"),
        (
            np.tile([1e150, -1e150], (4, 1)),
            1.0,
            {"wheel_noise": (1e290, 0.0)},
            "poses overflow the floats",
        ),
    ],
)
def test_travel_that_overflows_is_refused_not_returned_as_nan(
    wheels, dt, options, message, backend
):
    with pytest.raises(ValueError, match=message):
        monte_carlo(ROBOT, wheels, dt, 5, seed=0, backend=backend, **options)
