"""diffdrive.dynamics: a velocity-commanded drive's delay, time constant, gain and
acceleration limit found again on synthetic logs at three noise levels, the refusals, and the
TurtleBot3 figures the guides quote."""

import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest

import docs_pages
from diffdrive.dynamics import VelocityResponse, cross_validate_response, identify_velocity_response
from records import assert_as_recorded

T = np.arange(0.0, 60.0, 0.02)
COMMAND_TIMES = np.arange(0.0, 60.0, 0.5)


def logged(noise, seed=0, delay=0.037, tau=0.12, gain=0.95, acceleration=math.inf):
    rng = np.random.default_rng(seed)
    commands = rng.uniform(-10, 10, (len(COMMAND_TIMES), 2))
    truth = VelocityResponse(delay, tau, gain, acceleration, np.zeros((2, 2)), 0.0)
    velocities = truth.predict(T, COMMAND_TIMES, commands, np.zeros(2))
    return commands, velocities + rng.normal(size=velocities.shape) * noise


@pytest.mark.slow
@pytest.mark.parametrize("noise", [0.01, 0.1, 0.5])
def test_the_response_comes_back_at_three_noise_levels(noise):
    """Gains within 2 %, the delay within 5 ms, the time constant within 5 %."""
    commands, measured = logged(noise)
    found = identify_velocity_response(T, measured, COMMAND_TIMES, commands)
    assert found.gain == pytest.approx(0.95, rel=0.02)
    assert found.delay == pytest.approx(0.037, abs=0.005)
    assert found.time_constant == pytest.approx(0.12, rel=0.05)
    assert found.rmse == pytest.approx(noise, rel=0.2, abs=0.02)
    assert np.all(np.sqrt(np.diag(found.covariance)) < [0.01, 0.01])


@pytest.mark.slow
def test_an_acceleration_limit_is_found_between_those_tried():
    commands, measured = logged(0.05, seed=1, acceleration=60.0)
    found = identify_velocity_response(
        T, measured, COMMAND_TIMES, commands, accelerations=(math.inf, 20.0, 40.0, 80.0, 160.0)
    )
    assert found.acceleration == pytest.approx(60.0, rel=0.1)  # 64: refined between 40 and 80
    assert found.gain == pytest.approx(0.95, rel=0.02)
    unlimited = identify_velocity_response(T, measured, COMMAND_TIMES, commands)
    assert unlimited.acceleration == math.inf  # none tried, none fitted


@pytest.mark.slow
def test_cross_validation_scores_each_block_with_a_response_identified_without_it():
    """Five blocks of a log of 60 s: each fold's response is the truth again (from the other
    48 s), its held-out RMSE is the noise, and it predicts far better than the wheels at their
    commands at once; every held-out sample is scored once, and nothing else."""
    commands, measured = logged(0.05, seed=2)
    found = cross_validate_response(T, measured, COMMAND_TIMES, commands, folds=5, segment=3.0)
    assert len(found.responses) == 5
    for response in found.responses:
        assert response.gain == pytest.approx(0.95, rel=0.02)
        assert response.delay == pytest.approx(0.037, abs=0.005)
        assert response.time_constant == pytest.approx(0.12, rel=0.05)
    np.testing.assert_allclose(found.rmse, 0.05, rtol=0.2)
    assert found.pooled == pytest.approx(0.05, rel=0.2)
    assert found.ratio < 0.1
    assert np.all(found.instant > 5 * found.rmse)
    assert np.isnan(found.predicted).sum() == 0  # 12 s blocks: four whole 3 s pieces each
    block = slice(600, 750)  # the second block's first piece: predicted from its own start
    again = found.responses[1].predict(T[block], COMMAND_TIMES, commands, measured[600])
    np.testing.assert_array_equal(found.predicted[block], again)


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"folds": 1}, "folds must be a whole number >= 2"),
        ({"folds": True}, "folds must be a whole number >= 2"),
        ({"segment": 0.0}, "segment must be a finite time > 0 s"),
        ({"folds": 30, "segment": 5.0}, "30 folds of a 60 s log are shorter than one 5 s"),
    ],
)
def test_cross_validation_refuses_folds_it_cannot_score(options, message):
    commands, measured = logged(0.05)
    with pytest.raises(ValueError, match=message):
        cross_validate_response(T, measured, COMMAND_TIMES, commands, **options)


STEP_TIMES = np.linspace(0.0, 1.0, 101)
RESPONSE_CASES = {
    # (delay, time constant, gain, limit, command): the closed form at t, wheel by wheel
    "lag": (
        (0.05, 0.1, 0.9, math.inf, [4.0, -2.0]),
        lambda t: np.outer(0.9 * (1 - np.exp(-np.maximum(t - 0.05, 0) / 0.1)), [4.0, -2.0]),
    ),
    "limit": (
        (0.0, 0.0, 1.0, 10.0, [4.0, -2.0]),
        lambda t: np.stack([np.minimum(10 * t, 4.0), -np.minimum(10 * t, 2.0)], axis=-1),
    ),
}
BACKENDS = ["python"] + (["numba"] if importlib.util.find_spec("numba") else [])


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("case", sorted(RESPONSE_CASES))
def test_each_backend_drives_the_response_as_the_closed_form_says(case, backend, monkeypatch):
    """A step of command from rest: a first-order lag after a delay, and a ramp at the limit
    with no lag; numba's loop and Python's give the same numbers to the bit."""
    from diffdrive.dynamics import response

    (delay, tau, gain, limit, command), closed = RESPONSE_CASES[case]
    monkeypatch.setattr(response, "_COMPILED", backend == "numba")
    found = response.simulate_response(
        STEP_TIMES, [0.0], [command], delay, np.zeros(2), gain, tau, limit
    )
    np.testing.assert_allclose(found, closed(STEP_TIMES), rtol=1e-12, atol=1e-12)
    if len(BACKENDS) == 2:
        monkeypatch.setattr(response, "_COMPILED", backend != "numba")
        other = response.simulate_response(
            STEP_TIMES, [0.0], [command], delay, np.zeros(2), gain, tau, limit
        )
        np.testing.assert_array_equal(found, other)


def test_logs_that_cannot_show_the_response_are_refused():
    commands, measured = logged(0.01)
    with pytest.raises(ValueError, match="constant command cannot show"):
        identify_velocity_response(T, measured, COMMAND_TIMES, np.ones_like(commands))
    with pytest.raises(ValueError, match="do not overlap"):
        identify_velocity_response(T, measured, COMMAND_TIMES + 100.0, commands)
    with pytest.raises(ValueError, match="must agree"):
        identify_velocity_response(T[:10], measured[:10], COMMAND_TIMES, commands)
    with pytest.raises(ValueError, match="must be finite"):
        identify_velocity_response(T, measured * np.nan, COMMAND_TIMES, commands)
    with pytest.raises(ValueError, match="max_delay must be finite and >= 0 s, got -1"):
        identify_velocity_response(T, measured, COMMAND_TIMES, commands, max_delay=-1)
    with pytest.raises(ValueError, match="accelerations must be limits > 0"):
        identify_velocity_response(T, measured, COMMAND_TIMES, commands, accelerations=(0.0,))


@pytest.mark.slow
def test_the_turtlebot3_example_prints_what_the_readme_quotes(capsys, tmp_path):
    """Five folds, over the stamps as recorded and over the simulator's sample times: the
    pooled RMSE with the response and at once, their ratio, and the share of the largest
    errors; the held-out response at most half the instant one over the sample times."""
    import importlib.util
    import re

    from data import data_folder

    path = Path(__file__).resolve().parents[1] / "examples" / "drive_response.py"
    spec = importlib.util.spec_from_file_location("drive_response", path)
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    script.main(["--bags", str(data_folder("ros-bags")), "--output", str(tmp_path / "f.png")])
    printed = capsys.readouterr().out
    assert_as_recorded("drive_response", printed)
    lines = printed.splitlines()
    readme = docs_pages.text(flat=True)
    scored = [line for line in lines if line.startswith("held-out wheel-velocity RMSE")]
    for line in scored:
        model, instant = re.findall(r"(\d\.\d{3}) rad/s", line)
        share = re.search(r"\((\d+\.\d)%;", line).group(1) + " %"
        for figure in (model, instant, share):
            assert figure in readme, figure
    restored = scored[1]
    ratio = float(re.search(r"\((\d+\.\d)%;", restored).group(1))
    assert ratio <= 50.0
    largest = re.search(r"carry (\d+)% of", restored).group(1)
    assert f"carry {largest} % of its squared error" in readme
    folds = [line for line in lines if line.startswith("fold ")]
    assert len(folds) == 5
    assert all("time constant 3" in line for line in folds)  # 31-35 ms
    assert (tmp_path / "f.png").stat().st_size > 0


KS, KV, KA, DT = 1.0, 3.0, 0.5, 0.005


def motor(volts):
    """The velocity (m/s) at each sample of a motor of kS 1 V, kV 3 V s/m, kA 0.5 V s^2/m
    driven from rest by ``volts`` held over each 5 ms step, simulated exactly; stiction holds
    it while the voltage does not pass kS."""
    alpha = math.exp(-KV * DT / KA)
    beta = (1.0 - alpha) / KV
    v, speeds = 0.0, []
    for volt in volts:
        speeds.append(v)  # the velocity at this sample's time, before its voltage acts
        if v == 0.0 and abs(volt) <= KS:
            continue
        friction = KS * np.sign(v if v != 0.0 else volt)
        moved = alpha * v + beta * (volt - friction)
        v = 0.0 if v != 0.0 and np.sign(moved) != np.sign(v) and abs(volt) <= KS else moved
    return np.array(speeds)


def sysid_routine(delay, noise=0.005, seed=0):
    """SysId's routine on ``motor``: 0.25 V/s quasistatic ramps and 7 V dynamic steps, both
    ways, one after another from rest; the velocity measured ``delay`` s late with ``noise``
    m/s."""
    ramp = np.arange(0.0, 40.0, DT) * 0.25
    step = np.full(int(3.0 / DT), 7.0)
    rest = np.zeros(int(1.0 / DT))
    volts = np.concatenate([ramp, rest, -ramp, rest, step, rest, -step, rest])
    speeds = motor(volts)
    lag = round(delay / DT)
    measured = np.concatenate([np.zeros(lag), speeds[: len(speeds) - lag]])
    rng = np.random.default_rng(seed)
    return np.arange(len(volts)) * DT, volts, measured + rng.normal(size=len(volts)) * noise


@pytest.mark.slow
@pytest.mark.parametrize("delay", [0.0, 0.02, 0.05])
def test_ks_kv_ka_from_sysids_routine_with_the_delay_from_the_data(delay):
    """Within 2 % of the truth, and within 1 % of SysId's regression given the true delay;
    the plain regression, not told the delay, misses kA."""
    from diffdrive.dynamics import identify_voltage_response
    from diffdrive.dynamics.voltage import _regression

    times, volts, measured = sysid_routine(delay)
    found = identify_voltage_response(times, volts, measured)
    gains = found.feedforward
    assert found.delay == pytest.approx(delay, abs=DT)
    for value, true in ((gains.ks, KS), (gains.kv, KV), (gains.ka, KA)):
        assert value == pytest.approx(true, rel=0.02)
    (alpha, beta, gamma), *_ = _regression(times, volts, measured, delay, 0.02)
    told = ((1 - alpha) / beta, -(1 - alpha) / beta * DT / math.log(alpha), -gamma / beta)
    for value, sysid in zip((gains.kv, gains.ka, gains.ks), told, strict=True):
        assert value == pytest.approx(sysid, rel=0.01)
    assert np.all(np.sqrt(np.diag(found.covariance)) < 0.02)
    assert gains.voltage(1.0, 2.0) == pytest.approx(gains.ks + gains.kv + 2 * gains.ka)
    if delay:  # the plain regression, the delay not given: kA 17 % and 46 % high
        (alpha, beta, _), *_ = _regression(times, volts, measured, 0.0, 0.02)
        plain = -(1 - alpha) / beta * DT / math.log(alpha)
        assert plain > 1.1 * KA


def test_a_log_driven_one_way_is_refused():
    from diffdrive.dynamics import identify_voltage_response

    times, volts, measured = sysid_routine(0.0)
    with pytest.raises(ValueError, match="driven both ways"):
        identify_voltage_response(times, np.abs(volts), np.abs(measured))


def test_feedforward_drives_a_twist_through_inverse_kinematics():
    import diffdrive as dd
    from diffdrive.dynamics import Feedforward

    robot = dd.DiffDrive(wheel_radius=0.05, track_width=0.3)
    gains = Feedforward(0.5, 0.2, 0.05)
    left, right = gains.wheel_voltages(robot, (1.0, 0.0, 2.0), (0.5, 0.0, -1.0))
    # wheels: (1 -+ 0.3) / 0.05 = 14 and 26 rad/s; their rates (0.5 +- 0.15) / 0.05 = 13, 7
    assert left == pytest.approx(0.5 + 0.2 * 14 + 0.05 * 13)
    assert right == pytest.approx(0.5 + 0.2 * 26 + 0.05 * 7)
    assert gains.wheel_voltages(robot, (0.0, 0.0, 0.0)) == (0.0, 0.0)


@pytest.mark.slow
def test_a_drivetrains_linear_and_angular_channels():
    """Each channel its own ``motor``: the linear driven by the routine, the angular (half the
    wheels' difference) by the routine a third of the way on; mixed into the two wheels, each
    channel's gains found within 2.5 %."""
    from diffdrive.dynamics import identify_drivetrain

    times, volts, linear = sysid_routine(0.0, seed=1)
    turning = np.roll(volts, len(volts) // 3)
    rng = np.random.default_rng(4)
    angular = motor(turning) + rng.normal(size=len(volts)) * 0.005
    wheels_volts = np.column_stack([volts - turning, volts + turning])
    speeds = np.column_stack([linear - angular, linear + angular])
    found = identify_drivetrain(times, wheels_volts, speeds)
    for channel in (found.linear, found.angular):
        gains = channel.feedforward
        for value, true in ((gains.ks, KS), (gains.kv, KV), (gains.ka, KA)):
            assert value == pytest.approx(true, rel=0.025)
    straight = np.column_stack([volts, volts])
    with pytest.raises(ValueError, match="the angular channel: kS needs the wheel driven both"):
        identify_drivetrain(times, straight, np.column_stack([linear, linear]))
