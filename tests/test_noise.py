"""diffdrive.calibration.noise: the noise model identified on synthetic runs with known terms, the
covariance it predicts held to the errors, and the refusals."""

import numpy as np
import pytest

import diffdrive as dd
from diffdrive import sensors
from diffdrive.calibration import noise
from diffdrive.evaluation import consistency
from diffdrive.sensor_noise import GyroNoise

ROBOT = dd.DiffDrive(wheel_radius=0.05, track_width=0.3)
T = np.arange(501) * 0.02
TRUE = {
    "k": 1e-4,
    "radius_sigma": 0.005,
    "track_sigma": 0.01,
    "reference_sigma": 0.005,
    "reference_heading_sigma": 0.01,
}


def runs(
    count,
    seed,
    geometry=(0.005, 0.005, 0.01),
    k=1e-4,
    reference=(0.005, 0.005, 0.01),
    times=T,
):
    """``count`` runs over ``times`` (10 s) on paths of their own (speeds, turns and weaving
    drawn), read by encoders with the given wheel noise and geometry spread, against a
    reference with noise."""
    rng = np.random.default_rng(seed)
    made, truths = [], []
    model = sensors.EncoderModel(geometry_sigma=geometry, wheel_noise=k)
    for _ in range(count):
        base, turn = rng.uniform(3, 8), rng.uniform(-4, 4)
        sway, rate = rng.uniform(0, 3), rng.uniform(0.2, 1.0)
        wheels = np.stack(
            [
                base - turn + sway * np.sin(rate * times[:-1]),
                base + turn - sway * np.sin(rate * times[:-1]),
            ],
            axis=-1,
        )
        path = dd.simulate(ROBOT, wheels, times=times)
        seed_of_run = int(rng.integers(2**31))
        read = sensors.encoder_readings(ROBOT, times, path.poses, model, seed=seed_of_run)
        truth = path.poses + rng.normal(size=path.poses.shape) * np.array(reference)
        made.append((np.diff(read.readings[0], axis=0), truth))
        truths.append(path.poses)
    return made, truths


@pytest.mark.slow
@pytest.mark.parametrize(
    ("seconds", "windows", "within"),
    [(10, 8, 0.25), (60, 30, 0.10)],
)
def test_the_terms_of_synthetic_runs_are_found(seconds, windows, within):
    """200 runs with all five terms: each found within 3 of its standard errors, and within
    25 % on runs of 10 s, 10 % on runs of 60 s cut into 30 windows. The per-run geometry is
    one draw a run, so 200 runs pin its sigmas to no better than 5 %; 10 s of driving shows
    each draw only through the noise, which leaves them 12 % (60 s: 6-7 %)."""
    times = np.arange(round(seconds / 0.02) + 1) * 0.02
    found = noise.identify(ROBOT, runs(200, seed=1, times=times)[0], windows=windows)
    errors = found.standard_errors()
    for name, true in TRUE.items():
        value = getattr(found, name)
        assert abs(value - true) <= 3 * errors[name], name
        assert value == pytest.approx(true, rel=within), name
    assert found.runs == 200
    assert found.terms == noise.TERMS


@pytest.mark.slow
def test_the_predicted_covariance_is_honest_on_runs_it_did_not_see():
    """The model identified on 150 runs predicts the covariance of 100 others: ANEES near 1
    and about 95 % of poses inside the 95 % ellipse."""
    model = noise.identify(ROBOT, runs(150, seed=2)[0])
    fresh, _ = runs(100, seed=3)
    estimates, covariances, truths = [], [], []
    for increments, truth in fresh:
        poses, predicted = noise.covariances(ROBOT, increments, truth[0], model)
        every = slice(25, None, 25)
        estimates.append(poses[every])
        covariances.append(predicted[every])
        truths.append(truth[every])
    result = consistency(
        np.concatenate(estimates), np.concatenate(covariances), np.concatenate(truths)
    )
    assert result.anees == pytest.approx(1.0, abs=0.25)
    assert result.inside_95 == pytest.approx(0.95, abs=0.04)


@pytest.mark.slow
def test_references_drawn_from_a_model_match_the_covariance_it_predicts():
    """2000 references drawn on one run: the sample covariance of their error at the end is
    the predicted one within 10 % (trace and each diagonal term), and ANEES over the run is
    within 5 % of 1; a generator seeded alike draws alike."""
    model = noise.NoiseModel(*TRUE.values(), np.zeros((5, 5)), 1, noise.TERMS)
    (increments, truth), *_ = runs(1, seed=4)[0]
    poses, predicted = noise.covariances(ROBOT, increments, truth[0], model)
    rng = np.random.default_rng(7)
    drawn = np.array(
        [noise.draw_reference(ROBOT, increments, truth[0], model, rng) for _ in range(2000)]
    )
    errors = drawn - poses
    found = np.cov(errors[:, -1].T)
    assert np.trace(found) == pytest.approx(np.trace(predicted[-1]), rel=0.1)
    np.testing.assert_allclose(np.diag(found), np.diag(predicted[-1]), rtol=0.1)
    every = slice(10, None, 10)
    nees = np.einsum(
        "dti,tij,dtj->dt",
        errors[:, every],
        np.linalg.inv(predicted[every]),
        errors[:, every],
    )
    assert nees.mean() / 3 == pytest.approx(1.0, abs=0.05)
    again = noise.draw_reference(ROBOT, increments, truth[0], model, np.random.default_rng(7))
    np.testing.assert_array_equal(again, drawn[0])


@pytest.mark.parametrize(
    ("terms", "message"),
    [
        ((-1e-4, 0, 0, 0, 0), "noise model k must be >= 0, got -0.0001"),
        ((1e-4, 0, 0, float("inf"), 0), "noise model reference_sigma must be finite"),
        ((1e-4, 0, 0, 0, float("nan")), "noise model reference_heading_sigma must be finite"),
        ((1e-4, 0, -0.01, 0, 0), "noise model track_sigma must be >= 0"),
    ],
)
def test_a_noise_model_with_a_negative_or_non_finite_term_is_refused(terms, message):
    """Built by hand: a negative k would be rooted into NaN draws, an infinite sigma into
    infinite covariances, a negative sigma squared into a valid-looking one."""
    with pytest.raises(ValueError, match=message):
        noise.NoiseModel(*terms, np.zeros((5, 5)), 1, noise.TERMS)


def test_what_the_runs_cannot_identify_is_refused_by_name():
    straight = [
        (
            np.full((200, 2), 0.1),
            np.column_stack([np.arange(201) * 0.005, 0 * np.arange(201), 0 * np.arange(201)]),
        )
    ] * 3
    with pytest.raises(ValueError, match="cannot identify track_sigma"):
        noise.identify(ROBOT, straight, terms=("k", "track_sigma", "reference_sigma"))
    one, _ = runs(1, seed=4)
    with pytest.raises(ValueError, match="needs 2 runs or more, got 1"):
        noise.identify(ROBOT, one)
    with pytest.raises(ValueError, match="terms must be some of"):
        noise.identify(ROBOT, one, terms=("alpha1",))
    with pytest.raises(ValueError, match="run 0: ground truth must be"):
        noise.identify(ROBOT, [(np.zeros((5, 2)), np.zeros((5, 3)))])
    with pytest.raises(TypeError, match="run 0: a run is a Run or"):
        noise.identify(ROBOT, [3])
    with pytest.raises(ValueError, match="at least one run"):
        noise.identify(ROBOT, [])


@pytest.mark.slow
def test_k_alone_is_odometrys_own():
    """Runs with wheel noise only: k found within 10 %, and the predicted covariance with the
    other terms at 0 is Odometry's."""
    made, _ = runs(100, seed=5, geometry=(0.0, 0.0, 0.0), reference=(1e-4, 1e-4, 1e-4))
    found = noise.identify(ROBOT, made, terms=("k", "reference_sigma"))
    assert found.k == pytest.approx(1e-4, rel=0.1)
    model = noise.NoiseModel(1e-4, 0.0, 0.0, 0.0, 0.0, np.zeros((5, 5)), 1, ("k",))
    increments, truth = made[0]
    _, predicted = noise.covariances(ROBOT, increments, truth[0], model)
    odometry = dd.Odometry(ROBOT, initial_pose=dd.Pose(*truth[0]), wheel_noise=1e-4)
    odometry.update_arrays("increments", *increments.T)
    np.testing.assert_allclose(predicted[-1], odometry.covariance, rtol=1e-12)


def test_the_gyro_terms_come_back_from_an_hour_standing_still():
    """An hour at 100 Hz: the angle random walk within 5 %, the rate random walk within 40 %
    (a few long clusters carry it), nothing invented where there is no term."""
    t = np.arange(0, 3600, 0.01)
    still = np.zeros((len(t), 3))
    model = sensors.GyroModel(noise=GyroNoise(angle_random_walk=2e-3, rate_random_walk=5e-5))
    rates = sensors.gyro_readings(ROBOT, t, still, model, seed=3).rates[0]
    found = noise.identify_gyro(t, rates)
    assert found.noise.angle_random_walk == pytest.approx(2e-3, rel=0.05)
    assert found.noise.rate_random_walk == pytest.approx(5e-5, rel=0.4)
    assert found.noise.bias_instability < 0.1 * 2e-3
    white = sensors.gyro_readings(
        ROBOT, t, still, sensors.GyroModel(noise=GyroNoise(angle_random_walk=1e-3)), seed=4
    )
    plain = noise.identify_gyro(t, white.rates[0])
    assert plain.noise.angle_random_walk == pytest.approx(1e-3, rel=0.05)
    assert plain.noise.rate_random_walk < 2e-6
    taus, deviations = found.taus, found.deviations
    assert deviations[0] == pytest.approx(2e-3 / np.sqrt(taus[0]), rel=0.05)  # N / sqrt(tau)
    # What an estimator assumes of the bias at the start: its instability, or a small floor.
    assert found.noise.initial_bias_sigma == max(found.noise.bias_instability, 1e-6)


def test_the_allan_deviation_refuses_what_it_cannot_use():
    with pytest.raises(ValueError, match="too short for the Allan deviation: 50 samples"):
        noise.allan_deviation(np.arange(50) * 0.01, np.zeros(50))
    uneven = np.cumsum(np.random.default_rng(0).uniform(0.005, 0.015, 500))
    with pytest.raises(ValueError, match="evenly spaced samples"):
        noise.allan_deviation(uneven, np.zeros(500))
    with pytest.raises(ValueError, match="must be finite"):
        noise.allan_deviation(np.arange(200) * 0.01, np.full(200, np.nan))


@pytest.mark.slow
def test_cross_validation_holds_each_group_out():
    """Three groups of runs of one robot: each scored by a model calibrated and identified on
    the other two; on runs like those, the predicted covariance is about right."""
    groups = {f"group {g}": runs(40, seed=10 + g)[0] for g in range(3)}
    scores = noise.cross_validate(ROBOT, groups)
    assert set(scores) == set(groups)
    for score in scores.values():
        assert score.model.runs == 80
        assert 0.5 < score.consistency.anees < 2.0
        assert score.consistency.inside_95 > 0.85
    with pytest.raises(ValueError, match="needs 2 groups of runs or more, got 1"):
        noise.cross_validate(ROBOT, {"only": groups["group 0"]})
