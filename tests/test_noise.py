"""diffdrive.calibration.noise: the noise model identified on synthetic runs with known terms, the
covariance it predicts held to the errors, and the refusals."""

import numpy as np
import pytest

import diffdrive as dd
from diffdrive import sensors
from diffdrive.calibration import noise
from diffdrive.evaluation import consistency
from diffdrive.sensor_noise import GyroNoise
from diffdrive.simulation import dead_reckon

ROBOT = dd.DiffDrive(wheel_radius=0.05, track_width=0.3)
T = np.arange(501) * 0.02
# The geometry's spread from group to group: the radii 0.5 % each and 0.8 correlated (they move
# together), the track 1 %, independent of them.
GEOMETRY = np.array(
    [[0.005**2, 0.8 * 0.005**2, 0.0], [0.8 * 0.005**2, 0.005**2, 0.0], [0.0, 0.0, 0.01**2]]
)
TRUE_REF = (0.005, 0.005, 0.01)
TRUE = {
    "k_left": 1e-4,
    "k_right": 3e-4,
    "radius_left_sigma": 0.005,
    "radius_right_sigma": 0.005,
    "track_sigma": 0.01,
    "reference_sigma": 0.005,
    "reference_heading_sigma": 0.01,
}


def runs(
    count,
    seed,
    geometry=GEOMETRY,
    k=(1e-4, 3e-4),
    reference=(0.005, 0.005, 0.01),
    times=T,
    per_group=1,
):
    """``count`` runs over ``times`` (10 s) on paths of their own (speeds, turns and weaving
    drawn), read by encoders with the given wheel noise, each ``per_group`` runs with one
    geometry error drawn from ``geometry`` (relative covariance), against a reference with
    noise: ``({group: [(increments, reference)]}, truths)``."""
    rng = np.random.default_rng(seed)
    made, truths = {}, []
    for run in range(count):
        if run % per_group == 0:
            error = rng.multivariate_normal(np.zeros(3), geometry)
            model = sensors.EncoderModel(
                radius_bias=tuple(error[:2]), track_bias=error[2], wheel_noise=k
            )
            group = made.setdefault(f"group {run // per_group}", [])
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
        group.append((np.diff(read.readings[0], axis=0), truth))
        truths.append(path.poses)
    return made, truths


def flat(groups):
    return [run for group in groups.values() for run in group]


MOTION_CAPTURE = (noise.MOTION_CAPTURE[0],) * 2 + (noise.MOTION_CAPTURE[1],)
HELD = {"reference_sigma": MOTION_CAPTURE[0], "reference_heading_sigma": MOTION_CAPTURE[2]}


def found_terms(model):
    """The terms ``TRUE`` names, as fitted."""
    left, right, track = model.sigmas
    return {
        "k_left": model.k_left,
        "k_right": model.k_right,
        "radius_left_sigma": left,
        "radius_right_sigma": right,
        "track_sigma": track,
        "reference_sigma": model.reference_sigma,
        "reference_heading_sigma": model.reference_heading_sigma,
    }


@pytest.mark.slow
@pytest.mark.parametrize("reference", ["motion capture, held", "5 mm and 0.01 rad, fitted"])
def test_the_terms_of_synthetic_runs_are_found(reference):
    """200 runs in 40 groups of 5, each group one draw of the geometry (correlated radii), the
    wheels' noise 1e-4 and 3e-4 m. Against motion capture held at its stated accuracy: each
    wheel's k within 10 % (standard errors of about 4 %; all seeds of
    benchmarks/bench_noise_model.py), every term within 3 of its standard errors, the radii's
    correlation found. Against a reference of 5 mm and 0.01 rad fitted with the rest, the
    reference's heading noise is hard to tell from the wheels' (k's standard errors 5-8 %):
    every term within 3 of its standard errors, k within 20 %."""
    held = reference.startswith("motion")
    groups, _ = runs(200, seed=1, per_group=5, reference=MOTION_CAPTURE if held else TRUE_REF)
    if held:
        found = noise.identify(ROBOT, groups, terms=noise.TERMS[:4], fixed=HELD)
    else:
        found = noise.identify(ROBOT, groups)
    errors = found.standard_errors()
    values = found_terms(found)
    truth = {**TRUE, **(HELD if held else {})}
    assert set(errors) == set(truth) - (set(HELD) if held else set())
    for name, value in values.items():
        assert abs(value - truth[name]) <= 3 * errors.get(name, 0.0), name
    within = 0.1 if held else 0.2
    assert found.k_left == pytest.approx(1e-4, rel=within)
    assert found.k_right == pytest.approx(3e-4, rel=within)
    assert found.correlation[0, 1] > 0.5
    assert (found.runs, found.groups) == (200, 40)


@pytest.mark.slow
def test_the_predicted_covariance_is_honest_on_runs_it_did_not_see():
    """The model identified on 150 runs (30 groups) predicts the covariance of 100 others:
    ANEES near 1 and about 95 % of poses inside the 95 % ellipse."""
    model = noise.identify(ROBOT, runs(150, seed=2, per_group=5)[0])
    fresh, _ = runs(100, seed=3)
    estimates, covariances, truths = [], [], []
    for increments, truth in flat(fresh):
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
    the predicted one within 10 % (trace and each diagonal term; the geometry's correlated),
    and ANEES over the run is within 5 % of 1; a generator seeded alike draws alike, and a
    geometry given is the one used."""
    model = noise.NoiseModel((1e-4, 3e-4), GEOMETRY, 0.005, 0.01)
    (increments, truth), *_ = flat(runs(1, seed=4)[0])
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
    exact = noise.NoiseModel(geometry=GEOMETRY)
    shifted = noise.draw_reference(ROBOT, increments, truth[0], exact, 0, geometry=[0.01, 0, 0])
    other = ROBOT.with_geometry(0.0505, 0.05, 0.3)
    np.testing.assert_allclose(
        shifted, dead_reckon(other, increments, truth[0]), rtol=0, atol=1e-12
    )


def test_the_unscented_spread_is_the_linear_one_for_a_small_geometry_error():
    """A tiny correlated geometry: the predicted covariance is J G J^T, J the poses'
    derivatives on the relative geometry, to 1e-6 of its size."""
    geometry = GEOMETRY * 1e-6
    (increments, truth), *_ = flat(runs(1, seed=5)[0])
    _, predicted = noise.covariances(
        ROBOT, increments, truth[0], noise.NoiseModel(geometry=geometry)
    )
    base = dead_reckon(ROBOT, increments, truth[0])
    jacobian = np.zeros((len(base), 3, 3))
    for index in range(3):
        step = np.zeros(3)
        step[index] = 1e-7
        other = ROBOT.with_geometry(*(np.array([0.05, 0.05, 0.3]) * (1 + step)))
        jacobian[:, :, index] = (dead_reckon(other, increments, truth[0]) - base) / 1e-7
    linear = np.einsum("tia,ab,tjb->tij", jacobian, geometry, jacobian)
    np.testing.assert_allclose(predicted, linear, rtol=0, atol=1e-4 * np.abs(linear).max())


@pytest.mark.parametrize(
    ("terms", "message"),
    [
        ({"wheel_noise": (-1e-4, 0.0)}, "wheel noise left must be a number >= 0 m, got -0.0001"),
        ({"wheel_noise": "1e-4"}, "noise model wheel_noise must be a WheelNoise"),
        ({"reference_sigma": float("inf")}, "noise model reference_sigma must be finite"),
        ({"reference_heading_sigma": np.nan}, "noise model reference_heading_sigma must be fin"),
        ({"geometry": np.diag([1e-4, 1e-4, -1e-4])}, "geometry must be positive semi-definite"),
        ({"geometry": np.array([[0, 1e-4, 0], [0, 0, 0], [0, 0, 0]])}, "must be symmetric"),
        ({"geometry": np.zeros(3)}, "geometry must be a finite .3, 3. matrix"),
        ({"geometry": np.full((3, 3), np.nan)}, "geometry must be a finite .3, 3. matrix"),
    ],
)
def test_a_noise_model_with_a_negative_or_non_finite_term_is_refused(terms, message):
    """Built by hand: a negative k would be rooted into NaN draws, an infinite sigma into
    infinite covariances, a geometry that is no covariance into NaN sigma points."""
    with pytest.raises(ValueError, match=message):
        noise.NoiseModel(**terms)
    with pytest.raises(ValueError, match="noise model track_sigma must be >= 0"):
        noise.NoiseModel.symmetric(1e-4, 0.0, -0.01)


def test_a_model_by_hand_is_symmetric_and_independent():
    model = noise.NoiseModel.symmetric(2e-4, 0.003, 0.01, 0.001, 0.02)
    assert (model.k_left, model.k_right, model.k) == (2e-4, 2e-4, 2e-4)
    np.testing.assert_allclose(model.geometry, np.diag([9e-6, 9e-6, 1e-4]))
    assert model.radius_sigma == pytest.approx(0.003)
    assert model.track_sigma == pytest.approx(0.01)
    np.testing.assert_array_equal(model.correlation, np.eye(3))


def test_what_the_runs_cannot_identify_is_refused_by_name():
    straight = [
        (
            np.full((200, 2), 0.1),
            np.column_stack([np.arange(201) * 0.005, 0 * np.arange(201), 0 * np.arange(201)]),
        )
    ] * 3
    with pytest.raises(ValueError, match="cannot identify track_sigma"):
        noise.identify(ROBOT, straight, terms=("k_left", "track_sigma", "reference_sigma"))
    one = flat(runs(1, seed=4)[0])
    with pytest.raises(ValueError, match="needs 2 or more, got 1"):
        noise.identify(ROBOT, one)
    with pytest.raises(ValueError, match="needs 2 or more, got 1"):
        noise.identify(ROBOT, {"one group": one * 3})
    with pytest.raises(ValueError, match="group 'empty' has no runs"):
        noise.identify(ROBOT, {"empty": [], "full": one})
    with pytest.raises(ValueError, match="terms must be some of"):
        noise.identify(ROBOT, one, terms=("alpha1",))
    with pytest.raises(ValueError, match="terms must be some of"):
        noise.identify(ROBOT, one, terms=("k",))
    with pytest.raises(ValueError, match="run 0: ground truth must be"):
        noise.identify(ROBOT, [(np.zeros((5, 2)), np.zeros((5, 3)))])
    with pytest.raises(TypeError, match="run 0: a run is a Run or"):
        noise.identify(ROBOT, [3])
    with pytest.raises(ValueError, match="at least one run"):
        noise.identify(ROBOT, [])


@pytest.mark.slow
def test_k_alone_is_odometrys_own():
    """Runs with wheel noise only: each wheel's k found within 10 %, and the predicted
    covariance with the other terms at 0 is Odometry's with those wheels."""
    made, _ = runs(100, seed=5, geometry=np.zeros((3, 3)), reference=(1e-4, 1e-4, 1e-4))
    found = noise.identify(ROBOT, flat(made), terms=("k_left", "k_right", "reference_sigma"))
    assert found.k_left == pytest.approx(1e-4, rel=0.1)
    assert found.k_right == pytest.approx(3e-4, rel=0.1)
    model = noise.NoiseModel((1e-4, 3e-4))
    increments, truth = flat(made)[0]
    _, predicted = noise.covariances(ROBOT, increments, truth[0], model)
    odometry = dd.Odometry(ROBOT, initial_pose=dd.Pose(*truth[0]), wheel_noise=(1e-4, 3e-4))
    odometry.update_arrays("increments", *increments.T)
    np.testing.assert_allclose(predicted[-1], odometry.covariance, rtol=1e-12)


def test_a_reference_of_stated_accuracy_is_held_there():
    """Fixed at motion capture's accuracy, the reference's terms stay there and are not
    fitted; the wheels' noise takes the errors."""
    made, _ = runs(6, seed=6, reference=(1e-4, 1e-4, 1e-4))
    metres, radians = noise.MOTION_CAPTURE
    fixed = {"reference_sigma": metres, "reference_heading_sigma": radians}
    found = noise.identify(ROBOT, made, terms=("k_left", "k_right"), fixed=fixed)
    assert (found.reference_sigma, found.reference_heading_sigma) == (metres, radians)
    assert found.terms == ("k_left", "k_right")
    assert set(found.standard_errors()) == {"k_left", "k_right"}
    with pytest.raises(ValueError, match=r"fixed terms must be some of .* not fitted"):
        noise.identify(ROBOT, made, fixed=fixed)


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
    """Eight groups of five runs of one robot, each group its own draw of the geometry: each
    scored by a model calibrated and identified on the other seven. One held-out group is
    one draw, so its own score varies: every group's ANEES under 3.5, and pooled over the
    groups' poses, ANEES and coverage about right, a little overconfident as a covariance
    estimated from seven draws must be (its inverse is too large on average: seeds 10, 30, 50
    gave ANEES 1.16, 1.17, 1.12 and 91, 90, 93 % inside the 95 % ellipse). By session, a
    group's whole session is held out with it."""
    groups = {f"group {g}": flat(runs(5, seed=10 + g, per_group=5)[0]) for g in range(8)}
    scores = noise.cross_validate_noise(ROBOT, groups)
    assert set(scores) == set(groups)
    for name, score in scores.items():
        assert score.model.runs == 35
        assert score.model.groups == 7
        assert name not in score.trained_on
        assert score.consistency.anees < 3.5
    nees = np.concatenate([score.consistency.nees[1:] for score in scores.values()])
    assert 0.8 < nees.mean() / 3 < 1.3
    assert 0.88 < np.mean(nees <= 7.815) < 0.98  # chi2(3)'s 95 % point
    four = {name: groups[name] for name in list(groups)[:4]}
    sessions = {"group 0": "a", "group 1": "a", "group 2": "b", "group 3": "c"}
    by_session = noise.cross_validate_noise(ROBOT, four, sessions=sessions)
    assert by_session["group 0"].trained_on == ("group 2", "group 3")
    assert by_session["group 2"].trained_on == ("group 0", "group 1", "group 3")
    with pytest.raises(ValueError, match="needs 2 groups of runs or more, got 1"):
        noise.cross_validate_noise(ROBOT, {"only": groups["group 0"]})
    with pytest.raises(ValueError, match="sessions gives no session for group 'group 3'"):
        noise.cross_validate_noise(ROBOT, four, sessions={g: "a" for g in list(four)[:3]})
    with pytest.raises(ValueError, match=r"holding out 'group 0' \(session 'a'\) leaves 1"):
        noise.cross_validate_noise(ROBOT, four, sessions={**sessions, "group 2": "a"})


def test_diffdrive_odometry_identifies_the_wheels_noise_on_a_logs_ground_truth(tmp_path, capsys):
    """A log with ground truth and no --k: each wheel's k is identified on it (the reference
    held at motion capture's accuracy), said with its standard errors, and the covariance
    written is Odometry's with those k; given (one for both wheels, or two), nothing is
    identified or said."""
    from data import data_folder
    from diffdrive.cli import main
    from diffdrive.io.optiodom import optiodom_robot, read_optiodom_run

    run_file = next((data_folder("optiodom-diffdrive") / "free" / "030120210006").glob("*run-01*"))
    robot_file = tmp_path / "robot.toml"
    robot_file.write_text("wheel_radius = 0.042\ntrack_width = 0.2\n")
    out = tmp_path / "odometry.csv"
    argv = ["odometry", str(run_file), "--robot", str(robot_file), "--covariance", "-o", str(out)]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    run = read_optiodom_run(run_file)
    held = dict(
        zip(("reference_sigma", "reference_heading_sigma"), noise.MOTION_CAPTURE, strict=True)
    )
    robot = optiodom_robot()
    found = noise.identify(
        robot, [(run.increments(), run.truth)], terms=noise.TERMS[:2], fixed=held
    )
    said = f"wheel noise: k = {found.k_left:.3g} m left, {found.k_right:.3g} m right"
    assert f"{said} (identified on the log's ground truth" in printed
    assert "the reference held at motion capture's 1 mm and 0.1 deg" in printed
    odometry = dd.Odometry(
        robot, initial_pose=dd.Pose(*run.truth[0]), wheel_noise=(found.k_left, found.k_right)
    )
    odometry.update_arrays("increments", *run.increments().T)
    written = np.genfromtxt(out, delimiter=",", names=True)
    assert written["cov_xx"][-1] == pytest.approx(odometry.covariance[0, 0], rel=1e-6)
    assert main([*argv, "--k", "1e-4"]) == 0
    assert "wheel noise" not in capsys.readouterr().out
    assert main([*argv, "--k", "1e-4", "2e-4"]) == 0
    assert "wheel noise" not in capsys.readouterr().out
    assert main([*argv, "--k-left", "1e-4", "--k-right", "2e-4"]) == 0  # before 0.9
    assert "wheel noise" not in capsys.readouterr().out


def test_identify_wheel_noise_finds_each_wheel_from_one_log_against_motion_capture():
    """One 10 s log read with k = (1e-4, 3e-4) m against a reference at motion capture's
    accuracy: each wheel's k within a factor of two and said with its errors; a log that
    stands still cannot identify them, and says why instead of giving numbers."""
    made, _ = runs(1, 11, geometry=np.zeros((3, 3)), reference=(0.001, 0.001, 0.0017))
    ((increments, truth),) = made["group 0"]
    found, said = noise.identify_wheel_noise(ROBOT, increments, truth)
    assert found is not None
    assert 0.5e-4 < found.left < 2e-4
    assert 1.5e-4 < found.right < 6e-4
    assert said.startswith("identified on the log's ground truth, +-")
    standing = np.zeros_like(increments)
    still = np.repeat(truth[:1], len(truth), axis=0)
    nothing, why = noise.identify_wheel_noise(ROBOT, standing, still)
    assert nothing is None
    assert why.startswith(("the ground truth could not identify them", "identified on the"))
