"""Evaluation: the paper's measures, ATE with alignment, RPE as evo defines it."""

import math

import numpy as np
import pytest

import diffdrive as dd
from diffdrive.evaluation import align, ate, consistency, rpe, run_errors, worst


def straight(n=11, step=0.1):
    return np.column_stack([np.arange(n) * step, np.zeros(n), np.zeros(n)])


def test_run_errors_worked_case():
    truth = straight()
    estimate = truth.copy()
    estimate[5] += [0.0, 0.03, math.radians(2)]
    estimate[-1] += [0.01, 0.0, math.radians(-1)]
    errors = run_errors(estimate, truth)
    assert errors.max_position == pytest.approx(0.03)
    assert errors.max_heading == pytest.approx(2.0)
    assert errors.final_position == pytest.approx(0.01)
    assert errors.final_heading == pytest.approx(1.0)
    assert worst([errors, run_errors(truth, truth)]) == errors


def test_ate_is_zero_after_aligning_a_rigidly_moved_trajectory():
    t = np.linspace(0, 6, 200)
    truth = np.column_stack([np.cos(t), np.sin(2 * t), t])
    moved = dd.batch.compose(np.array([0.4, -1.2, 0.7]), truth)
    assert ate(moved, truth) > 0.5
    assert ate(moved, truth, aligned=True) == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(align(moved, truth), truth, atol=1e-12)


def test_ate_is_the_rmse_of_position_errors():
    truth = straight(5)
    estimate = truth + np.array([[0, 0.1, 0], [0, -0.1, 0], [0, 0.1, 0], [0, -0.1, 0], [0, 0.1, 0]])
    assert ate(estimate, truth) == pytest.approx(0.1)


def test_rpe_of_a_constant_heading_bias():
    """Odometry that turns 1 degree a step too far: each 1-step motion is off by 1 degree."""
    n = 20
    truth = straight(n + 1)
    estimate = np.zeros_like(truth)
    for k in range(n):  # the odometry's own steps of 0.1 m with a 1 degree extra turn
        estimate[k + 1] = dd.batch.compose(estimate[k], np.array([0.1, 0.0, math.radians(1)]))
    for pairs in ("consecutive", "all"):
        translation, rotation = rpe(estimate, truth, 1, unit="poses", pairs=pairs)
        assert rotation == pytest.approx(1.0)
        assert translation == pytest.approx(0.0, abs=1e-12)
        # Over 0.19 m (two steps of 0.1 m) the motion's end is off by the first step's turn.
        translation, rotation = rpe(estimate, truth, 0.19, unit="m", pairs=pairs)
        assert rotation == pytest.approx(2.0)
        assert translation == pytest.approx(0.1 * math.sin(math.radians(1)), rel=1e-3)


def test_rpe_and_ate_refuse_bad_input():
    truth = straight()
    with pytest.raises(ValueError, match="must both have shape"):
        ate(truth[:5], truth)
    with pytest.raises(ValueError, match="needs the times"):
        rpe(truth, truth, 1.0, unit="s")
    with pytest.raises(ValueError, match=r"no pair of poses is 5\.0 m apart"):
        rpe(truth, truth, 5.0)
    bad = truth.copy()
    bad[3, 1] = math.nan
    with pytest.raises(ValueError, match=r"estimate must be finite; pose 3 is"):
        ate(bad, truth)
    with pytest.raises(ValueError, match="at least one run"):
        worst([])
    with pytest.raises(ValueError, match="pairs must be one of consecutive, all"):
        rpe(truth, truth, 1.0, pairs="some")


# -- against evo -------------------------------------------------------------------------------


def evo_pair():
    """The trajectories behind the evo figures below: a truth at 100 Hz and the odometry of a
    robot with other wheels at 20 Hz, its clock 3 ms late."""
    robot = dd.DiffDrive(wheel_radius=0.042, track_width=0.2)
    biased = dd.DiffDrive(left_wheel_radius=0.0415, right_wheel_radius=0.0423, track_width=0.205)

    def history(t):
        return np.stack([6 + 3 * np.sin(t), 6 - 3 * np.sin(0.7 * t)], -1)

    truth = dd.simulate(robot, history, dt=0.01, duration=12.0)
    estimate = dd.simulate(biased, history, dt=0.05, duration=12.0)
    return truth, estimate


# Computed by evo 1.38.1 on these trajectories written as TUM files (truth.tum; estimate.tum
# with the times + 0.003 s), each with --t_max_diff 0.01 --t_offset -0.003, for example
# `evo_rpe tum truth.tum estimate.tum --delta 1 --delta_unit m -r angle_deg --all_pairs`;
# the RMSE from the saved results (--save_results).
EVO_ATE = {False: 0.204252238655749, True: 0.023702159355531358}  # evo_ape, evo_ape -a
EVO_RPE = [  # (delta, unit, pairs, pairs along the truth, RMSE m, RMSE deg)
    (1.0, "m", "consecutive", False, 0.046668502484007064, 6.906829395363205),
    (1.0, "m", "all", False, 0.04589424970462187, 5.240322451389079),
    (5, "poses", "consecutive", False, 0.0003344424932811086, 0.439025933072793),
    (5, "poses", "all", False, 0.00033614763212072725, 0.4406875119619212),
    (0.5, "m", "consecutive", True, 0.014937868067401584, 3.5127552157726467),
]


@pytest.fixture(scope="module")
def evo_files(tmp_path_factory):
    from diffdrive.io.trajectories import write_trajectory

    folder = tmp_path_factory.mktemp("evo")
    truth, estimate = evo_pair()
    write_trajectory(folder / "truth.tum", truth.times, truth.poses, "tum")
    write_trajectory(folder / "estimate.tum", estimate.times + 0.003, estimate.poses, "tum")
    return folder


def paired(folder):
    from diffdrive.evaluation import associate
    from diffdrive.io.trajectories import read_trajectory

    times, estimate = read_trajectory(folder / "estimate.tum")
    truth_times, truth = read_trajectory(folder / "truth.tum")
    i, j = associate(times, truth_times, 0.01, -0.003)
    assert len(i) == 241
    return estimate[i], truth[j]


@pytest.mark.parametrize("aligned", [False, True])
def test_ate_equals_evo(evo_files, aligned):
    estimate, truth = paired(evo_files)
    assert ate(estimate, truth, aligned=aligned) == pytest.approx(EVO_ATE[aligned], rel=1e-9)


@pytest.mark.parametrize(("delta", "unit", "pairs", "from_truth", "metres", "degrees"), EVO_RPE)
def test_rpe_equals_evo_in_both_pair_modes(
    evo_files, delta, unit, pairs, from_truth, metres, degrees
):
    estimate, truth = paired(evo_files)
    translation, rotation = rpe(
        estimate, truth, delta, unit, pairs=pairs, pairs_from_truth=from_truth
    )
    assert translation == pytest.approx(metres, rel=1e-9)
    assert rotation == pytest.approx(degrees, rel=1e-9)


def test_the_cli_pairs_by_time_like_evo(evo_files, capsys):
    import json

    from diffdrive.cli import main

    argv = [
        str(evo_files / "estimate.tum"),
        "--truth",
        str(evo_files / "truth.tum"),
        "--t-offset",
        "-0.003",
        "--rpe",
        "1",
        "--rpe-pairs",
        "all",
        "--json",
    ]
    assert main(["evaluate", *argv]) == 0
    metrics = json.loads(capsys.readouterr().out)
    assert metrics["poses_compared"] == 241
    assert metrics["ate_aligned_m"] == pytest.approx(EVO_ATE[True], rel=1e-9)
    assert metrics["rpe_1m_all_m"] == pytest.approx(EVO_RPE[1][4], rel=1e-9)


def test_interpolation_follows_the_arc():
    from diffdrive.evaluation import interpolate

    robot = dd.DiffDrive(wheel_radius=0.05, track_width=0.3)
    fine = dd.simulate(robot, np.tile([6.0, 9.0], (100, 1)), dt=0.01)
    coarse = fine.poses[::10]
    at = fine.times[3:95]
    np.testing.assert_allclose(
        interpolate(fine.times[::10], coarse, at), fine.poses[3:95], atol=1e-12
    )


@pytest.mark.parametrize(
    ("times", "poses", "message"),
    [
        ([0.0, 1.0, 1.0, 2.0], np.zeros((4, 3)), r"times\[2\] = 1.0 does not come after 1.0"),
        ([2.0, 1.0, 0.0], np.zeros((3, 3)), r"times\[1\] = 1.0 does not come after 2.0"),
        ([0.0, np.nan, 2.0], np.zeros((3, 3)), r"times\[1\] is nan"),
        ([0.0, 1.0, 2.0], [[0, 0, 0], [0, np.nan, 0], [0, 0, 0]], "pose 1 is not"),
    ],
)
def test_interpolation_refuses_stamps_out_of_order_and_poses_not_finite(times, poses, message):
    """Named: a repeated last stamp gave 0 / 0 there, stamps going back were called out of
    range, and a NaN pose came back as NaN poses along its arcs without a word."""
    from diffdrive.evaluation import interpolate

    with pytest.raises(ValueError, match=message):
        interpolate(np.array(times), np.array(poses, dtype=float), [0.5])


def test_positions_without_headings_are_interpolated_along_straight_lines():
    """GPS fixes (every heading NaN): linear in x and y, the heading NaN; one NaN heading
    among finite ones is still refused."""
    from diffdrive.evaluation import interpolate

    fixes = np.array([[0.0, 0.0, np.nan], [2.0, 4.0, np.nan], [2.0, 0.0, np.nan]])
    found = interpolate([0.0, 1.0, 3.0], fixes, [0.25, 2.0])
    np.testing.assert_allclose(found[:, :2], [[0.5, 1.0], [2.0, 2.0]], atol=1e-15)
    assert np.isnan(found[:, 2]).all()
    fixes[1, 2] = 0.0
    with pytest.raises(ValueError, match="pose 0 is not"):
        interpolate([0.0, 1.0, 3.0], fixes, [0.25])


def test_consistency_by_hand():
    """Two poses, diagonal covariances: NEES by hand; the first, exact start is left out."""
    truth = np.zeros((3, 3))
    estimate = np.array([[0.0, 0.0, 0.0], [0.1, -0.2, 0.05], [0.0, 0.6, 2 * math.pi - 0.1]])
    covariances = np.array(
        [np.zeros((3, 3)), np.diag([0.01, 0.04, 0.01]), np.diag([1, 0.09, 0.01])]
    )
    result = consistency(estimate, covariances, truth)
    nees = [0.1**2 / 0.01 + 0.2**2 / 0.04 + 0.05**2 / 0.01, 0.6**2 / 0.09 + 0.1**2 / 0.01]
    assert np.isnan(result.nees[0])
    np.testing.assert_allclose(result.nees[1:], nees)
    assert result.anees == pytest.approx(np.mean(nees) / 3)
    assert (result.used, result.dof) == (2, 3)
    assert result.inside_95 == 1.0
    assert result.inside_50 == 0.5  # 2.25 <= 2.366 (chi-square 3, 50 %) < 5.0
    gps = truth.copy()
    gps[:, 2] = np.nan  # a truth without headings: positions only
    positions = consistency(estimate, covariances, gps)
    assert positions.dof == 2
    np.testing.assert_allclose(positions.nees[1:], [1.0 + 1.0, 4.0])


@pytest.mark.slow
def test_odometrys_covariance_is_honest_over_many_robots():
    """10^4 robots whose wheels have exactly Odometry's noise (diffdrive.sensors): the final
    poses' NEES against Odometry's covariance averages 1 (ANEES within 5 %), and 95 % of the
    truths lie inside the 95 % ellipse."""
    from diffdrive import sensors

    robot = dd.DiffDrive(wheel_radius=0.05, track_width=0.3)
    t = np.arange(201) * 0.02
    wheels = np.stack([6 + 3 * np.sin(0.9 * t[:-1]), 6 - 3 * np.cos(0.6 * t[:-1])], axis=-1)
    path = dd.simulate(robot, wheels, times=t)
    model = sensors.EncoderModel(wheel_noise=1e-4)
    readings = sensors.encoder_readings(robot, t, path.poses, model, robots=10_000, seed=11)
    finals, covariances = [], []
    for angles in readings.readings:
        odometry = dd.Odometry(robot, initial_pose=dd.Pose(*path.poses[0]), wheel_noise=1e-4)
        odometry.update_arrays("positions", *angles.T, t)
        finals.append(odometry.pose.to_array())
        covariances.append(odometry.covariance)
    truth = np.repeat(path.poses[-1:], 10_000, axis=0)
    result = consistency(np.array(finals), np.array(covariances), truth)
    assert result.anees == pytest.approx(1.0, abs=0.05)
    assert result.inside_95 == pytest.approx(0.95, abs=0.012)
    assert result.inside_50 == pytest.approx(0.50, abs=0.03)


def test_consistency_refuses_what_it_cannot_measure():
    with pytest.raises(ValueError, match="shape"):
        consistency(np.zeros((2, 3)), np.zeros((3, 3, 3)), np.zeros((2, 3)))
    with pytest.raises(ValueError, match="no pose has a positive definite covariance"):
        consistency(np.zeros((2, 3)), np.zeros((2, 3, 3)), np.zeros((2, 3)))
    with pytest.raises(ValueError, match="covariances must be finite"):
        consistency(np.zeros((2, 3)), np.full((2, 3, 3), np.nan), np.zeros((2, 3)))


def test_a_dead_reckoned_path_is_started_where_the_fixes_place_it():
    """The path drawn at the origin, fixes of the same path moved by a rigid motion and seen
    by a receiver 0.3 m ahead of the body: the start is the moved start, the residual 0."""
    from diffdrive.estimation import Measurement
    from diffdrive.estimation.measurements import start_in_frame

    robot = dd.DiffDrive(0.05, 0.3)
    times = np.arange(201) * 0.05
    wheels = np.column_stack([8 + 3 * np.sin(times[:-1]), 8 - 3 * np.sin(0.7 * times[:-1])])
    path = dd.simulate(robot, wheels, times=times).poses
    motion = np.array([4.0, -2.0, 0.8])
    placed = dd.batch.compose(motion, path)
    arm = (0.3, 0.0)
    receiver = dd.batch.compose(placed, np.array([*arm, 0.0]))
    fixes = [
        Measurement.make("position", t, receiver[k, :2], np.eye(2) * 1e-4, arm)
        for k, t in list(enumerate(times))[::20]
    ]
    start, covariance, rms = start_in_frame(times, path, fixes)
    np.testing.assert_allclose(start, placed[0], atol=1e-9)
    assert rms < 1e-9
    assert covariance[0, 0] == pytest.approx(1e-4)  # the residual's floor of 1 cm, squared


def test_covariances_are_interpolated_entry_by_entry():
    from diffdrive.evaluation import interpolate_covariances

    first, second = np.diag([1.0, 2.0, 3.0]), np.full((3, 3), 0.5) + np.eye(3)
    got = interpolate_covariances([0.0, 2.0], [first, second], [0.0, 0.5, 2.0])
    np.testing.assert_allclose(got, [first, 0.75 * first + 0.25 * second, second])
