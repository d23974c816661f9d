"""EstimatorSettings: each part checks itself and names what is wrong; the estimator's faces
take one value; and every estimate is what it was before the settings value existed.

The before/after table: ``estimates_before.json`` holds what each case below gave at commit
54e8c60, spelled the old way (26 keywords on ``PoseEstimator``, ``**options`` on
``estimate_trajectory``, ``gyro_odometry`` and ``GyroOdometry``), and the CLI's output files
and lines; the cases here are the same calls spelled with ``EstimatorSettings``. They agreed
to the last bit when the record was taken; the test allows 1e-7 relative so that another
processor's rounding does not fail it. The whole-log cases with a gyro, and the command
line's, were taken again when a whole log began to weigh how far the gyro's samples leave
each turn open and to identify the wheels' noise against the gyro (a change of the model,
measured in ``test_wheel_turns.py``), and the stream fed rates with them; the other streaming
cases still hold 54e8c60's."""

from __future__ import annotations

import contextlib
import dataclasses
import inspect
import io
import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import diffdrive as dd
from diffdrive.estimation import (
    Encoders,
    EstimatorSettings,
    FixOffset,
    Gate,
    Gyro,
    GyroNoise,
    GyroOdometry,
    Measurement,
    PoseEstimator,
    Prior,
    SlipTest,
    WholeLog,
    Window,
    estimate_trajectory,
    gyro_odometry,
    measurements_of,
    rotation_from_rpy,
)
from diffdrive.sensor_noise import DEFAULT, DEFAULT_GYRO
from records import _same

BEFORE = Path(__file__).with_name("estimates_before.json")
R1 = dd.DiffDrive(0.05, 0.3)
R2 = dd.SkidSteer(0.1, 0.45, -0.35, icr_x=0.03)
G = GyroNoise(2e-2, 1e-3, 5e-2)


def log(seed: int, robot, n: int = 600, dt: float = 0.01, still: int = 80):
    """A drive standing for ``still`` steps first: increments with noise, a biased noisy
    gyro, late poses and wandering fixes of the truth."""
    rng = np.random.default_rng(seed)
    t = np.arange(n + 1) * dt
    w = np.column_stack([6 + 3 * np.sin(0.7 * t[:-1] + seed), 7 + 2 * np.cos(0.5 * t[:-1])])
    w[:still] = 0.0
    truth = dd.simulate(robot, w, dt=dt).poses
    inc = w * dt + rng.normal(0, 1e-3, w.shape) * (w != 0)
    omega = np.diff(np.unwrap(truth[:, 2])) / dt
    rates = np.concatenate([[omega[0]], omega]) + 0.01 + rng.normal(0, 2e-3, n + 1)
    k = np.arange(still + 20, n, 37)
    poses = truth[k] + rng.normal(0, [0.02, 0.02, 0.01], (len(k), 3))
    fk = np.arange(still + 5, n, 9)
    drift = 0.002 * np.arange(len(fk))[:, None]
    fixes = truth[fk, :2] + rng.normal(0, 0.05, (len(fk), 2)) + drift
    return t, inc, Gyro(t, rates), truth, t[k], poses, t[fk], fixes


def stream(estimator, robot, seed: int, heading: str, rates: int = 0) -> list:
    """A streaming estimator fed ``log(seed)``: gyro angles (or ``rates`` 1 or 3 rates)
    unless the heading is the wheels', poses 0.05 s late."""
    t, inc, gyro, _, pk, poses, _, _ = log(seed, robot)
    out: list = []
    j = 0
    for i in range(len(inc)):
        reading: dict = {}
        if rates:
            r = gyro.rates[i + 1]
            reading["gyro_rate"] = (0.0, 0.0, r) if rates == 3 else r
        elif heading != "wheels":
            ends = gyro.angles(t[i : i + 2])
            reading["gyro_angle"] = ends[1] - ends[0]
        estimator.update_increments(inc[i, 0], inc[i, 1], t[i + 1], **reading)
        while j < len(pk) and pk[j] + 0.05 <= t[i + 1]:
            estimator.add_pose(pk[j], poses[j], [0.02, 0.02, 0.01])
            j += 1
        if i % 50 == 0:
            p = estimator.pose
            out += [p.x, p.y, p.theta, *estimator.covariance.ravel()]
    e = estimator
    return [*out, *e.state, *e.state_covariance.ravel(), e.accepted, e.rejected, e.slip_score]


def whole(estimate, rows: int = 12) -> list:
    """An ``Estimate`` at ``rows`` rows: poses, covariances, states, twists and theirs, the
    flags, the likelihood and the lines that say what was used."""
    idx = np.linspace(0, len(estimate.times) - 1, rows).astype(int)
    arrays = (
        estimate.poses,
        estimate.covariances,
        estimate.states,
        estimate.twists,
        estimate.twist_covariances,
    )
    numbers = [x for a in arrays for x in a[idx].ravel().tolist()]
    counts = [float(estimate.slip.sum()), float(estimate.rejected), estimate.log_likelihood]
    return numbers + counts + list(estimate.settings)


def library_cases() -> dict[str, list]:
    S = EstimatorSettings
    t, inc, gyro, truth, pk, poses, fk, fixes = log(5, R2)
    pm = [
        Measurement.make("pose", a, b, [0.02, 0.02, 0.01]) for a, b in zip(pk, poses, strict=True)
    ]
    fm = measurements_of("position", fk, fixes, 0.05)
    every = S(
        "fused",
        method="rk2",
        wheel_noise=(1e-4, 2e-4),
        gyro_noise=G,
        bias=0.005,
        turn_scale=Prior(1.01, 0.05),
        distance_scale=Prior(0.99, 0.02),
        fix_offset=FixOffset(0.01, 0.05),
        window=Window(3.0, 0.2),
        gate=Gate(0.99, "inflate"),
        slip=SlipTest(8.0, 50.0, 2.0),
    )
    mounted = S(
        "gyro",
        mounting=rotation_from_rpy(0.0, 0.0, 0.0),
        bias=0.01,
        encoders=Encoders(max_wheel_speed=50.0),
    )
    odometry = GyroOdometry(
        R1, S(wheel_noise=2e-4, gyro_noise=G), initial_pose=dd.Pose(0.1, 0.2, 0.3)
    )
    t4, inc4, gyro4, *_ = log(4, R1)
    for i in range(len(inc4)):
        odometry.update(*inc4[i], float(np.diff(gyro4.angles(t4[i : i + 2]))[0]), 0.01)
    identified = S(whole_log=WholeLog(fixes="identified"))
    t6, inc6, *_ = log(6, R1)
    t7, inc7, gyro7, *_ = log(7, R1)
    records = estimate_trajectory(
        R1, t7, inc7, gyro=gyro7, settings=S(whole_log=WholeLog(records=True))
    ).records
    assert records is not None
    t8, inc8, gyro8, *_ = log(8, R1)
    by_gyro = gyro_odometry(R1, t8, inc8, gyro8, S("gyro", bias=0.01, wheel_noise=2e-4))
    t9, inc9, gyro9, *_ = log(9, R1)
    found = gyro_odometry(R1, t9, inc9, gyro9)
    start = dict(initial_pose=(0.0, 0.0, 0.0), initial_covariance=np.eye(3) * 1e-3)
    return {
        "stream wheels": stream(
            PoseEstimator(
                R1, S("wheels", wheel_noise=1e-4), initial_pose=dd.Pose(), initial_time=0.0
            ),
            R1,
            1,
            "wheels",
        ),
        "stream fused, every setting": stream(
            PoseEstimator(R2, every, initial_time=0.0, **start), R2, 2, "fused"
        ),
        "stream gyro heading, three rates through a mounting": stream(
            PoseEstimator(R1, mounted, initial_time=0.0), R1, 3, "gyro", rates=3
        ),
        "GyroOdometry": [*odometry.state, *odometry.state_covariance.ravel()],
        "whole fused, identified gyro, smoothed": whole(
            estimate_trajectory(R2, t, inc, gyro=gyro, measurements=pm)
        ),
        "whole fused, given gyro, filtered, interval slip test": whole(
            estimate_trajectory(
                R2,
                t,
                inc,
                gyro=gyro,
                measurements=pm,
                smooth=False,
                settings=S(
                    gyro_noise=G,
                    bias=0.01,
                    turn_scale=Prior(sigma=0.05),
                    gate=Gate(0.99),
                    whole_log=WholeLog(slip_episodes=False),
                ),
            )
        ),
        "whole wheels, commanded": whole(
            estimate_trajectory(
                R1,
                t6,
                inc6,
                settings=S("wheels", wheel_noise=3e-4),
                commanded=np.tile([6.0, 7.0], (600, 1)),
            )
        ),
        "whole identified fixes": whole(
            estimate_trajectory(R2, t, inc, gyro=gyro, measurements=fm, settings=identified)
        ),
        "whole identified fixes, distance scale given": whole(
            estimate_trajectory(
                R2,
                t,
                inc,
                measurements=fm,
                settings=identified.replace(heading="wheels", distance_scale=Prior(1.0, 0.01)),
            )
        ),
        "whole given fixes with offset": whole(
            estimate_trajectory(
                R2,
                t,
                inc,
                gyro=gyro,
                measurements=fm,
                initial_pose=truth[0],
                initial_covariance=np.eye(3) * 1e-4,
                settings=S(fix_offset=FixOffset(0.02, 0.1), distance_scale=Prior(sigma=0.02)),
            )
        ),
        "records": [
            *records.gain[::50].ravel().tolist(),
            *records.before_covariance[::50].ravel().tolist(),
        ],
        "gyro_odometry": [
            *by_gyro.poses[::50].ravel().tolist(),
            *by_gyro.covariances[::50].ravel().tolist(),
            *by_gyro.settings,
        ],
        "gyro_odometry identified": [
            *found.poses[::50].ravel().tolist(),
            *found.bias[::50].tolist(),
            *found.settings,
        ],
    }


# The command line: the built-in log with a biased gyro column and fixes every 1 s.
CLI_RUNS = {
    "fused smoothed fixes": ["--measurements", "fixes.csv", "--smooth", "--covariance", "--twist"],
    "wheels heading gate": [
        "--heading", "wheels", "--measurements", "fixes.csv", "--gate", "0.99",
        "--k-left", "2e-4", "--k-right", "1e-4",
    ],
    "turn scale, bias, interval": [
        "--turn-scale-sigma", "0.05", "--gyro-bias", "0.003", "--slip-test", "interval",
        "--smooth", "--method", "rk2",
    ],
    "gyro heading filtered": ["--heading", "gyro", "--measurements", "fixes.csv", "--covariance"],
    "gyro odometry, defaults": ["--covariance", "--twist"],
    "gyro odometry, gyro heading, interval": [
        "--heading", "gyro", "--gyro-bias", "0.003", "--slip-test", "interval", "--k-left", "3e-4",
        "--k-right", "1e-4",
    ],
}  # fmt: skip


def _write_table(path: Path, columns: dict) -> None:
    names = list(columns)
    rows = np.column_stack([columns[name] for name in names])
    lines = [",".join(names), *(",".join(map(repr, r)) for r in rows.tolist())]
    path.write_text("\n".join(lines))


def cli_cases(folder: Path, before: dict[str, list] | None = None) -> dict[str, list]:
    """The command line's cases; with ``before`` (the record), each file's columns as the
    record has them (estimate writes the twist always since 0.9: columns the record lacks)."""
    from diffdrive.cli import main
    from diffdrive.demo import EXAMPLE_TICKS_PER_REVOLUTION, example_encoder_log

    table = example_encoder_log()
    gyro = np.gradient(np.unwrap(table["theta"]), table["t"]) + 0.003
    _write_table(folder / "log.csv", {**table, "gyro_z": gyro})
    rng = np.random.default_rng(0)
    every = slice(0, None, 20)
    noise = rng.normal(size=(len(table["t"][every]), 2)) * 0.05
    sigma = np.full(len(noise), 0.05)
    fixes = {
        "t": table["t"][every],
        "x": table["x"][every] + noise[:, 0],
        "y": table["y"][every] + noise[:, 1],
        "sigma_x": sigma,
        "sigma_y": sigma,
    }
    _write_table(folder / "fixes.csv", fixes)
    ticks = ["--ticks-per-revolution", str(EXAMPLE_TICKS_PER_REVOLUTION)]
    out = {}
    for name, extra in CLI_RUNS.items():
        printed = io.StringIO()
        with contextlib.redirect_stdout(printed):
            assert main(["odometry", "log.csv", *ticks, *extra, "-o", "o.csv"]) == 0, name
        written = np.genfromtxt(folder / "o.csv", delimiter=",", names=True)
        names = written.dtype.names
        assert names is not None
        if before is not None:
            names = tuple(before["cli " + name][0].split(","))
        rows = np.linspace(0, len(written) - 1, 15).astype(int)
        numbers = [float(written[c][r]) for c in names for r in rows]
        out["cli " + name] = [",".join(names), *numbers, *printed.getvalue().splitlines()]
    return out


def _assert_as_before(name: str, now: list, before: list) -> None:
    assert len(now) == len(before), name
    numbers = [(a, b) for a, b in zip(now, before, strict=True) if not isinstance(b, str)]
    np.testing.assert_allclose(
        *np.array(numbers, dtype=float).T, rtol=1e-7, atol=1e-13, err_msg=name
    )
    lines = [(a, b) for a, b in zip(now, before, strict=True) if isinstance(b, str)]
    for line, recorded in lines:
        assert isinstance(line, str), (name, line)
        assert _same(line, recorded), (name, line, recorded)


@pytest.mark.slow
def test_every_estimate_is_what_it_was_before_the_settings_value(tmp_path, monkeypatch):
    """The table of cases (module docstring) against the record taken with the old spelling."""
    before = json.loads(BEFORE.read_text())
    monkeypatch.chdir(tmp_path)
    now = {**library_cases(), **cli_cases(tmp_path, before)}
    assert sorted(now) == sorted(before)
    for name, values in now.items():
        _assert_as_before(name, values, before[name])


def test_the_faces_take_one_settings_value():
    """PoseEstimator takes at most 7 parameters (WPILib's: 7), estimate_trajectory at most 10,
    and no face forwards unchecked keywords."""
    faces = {
        PoseEstimator.__init__: 7 + 1,  # self
        GyroOdometry.__init__: 7 + 1,
        estimate_trajectory: 10,
        gyro_odometry: 10,
    }
    for face, most in faces.items():
        parameters = inspect.signature(face).parameters.values()
        assert len(parameters) <= most, face
        assert not any(p.kind is p.VAR_KEYWORD for p in parameters), face
        assert "settings" in inspect.signature(face).parameters


def test_the_default_is_one_value_and_each_part_has_its_own():
    settings = EstimatorSettings()
    assert settings == EstimatorSettings(
        heading="fused",
        wheel_noise=None,
        turn_scale=Prior(1.0, 0.0),
        slip=SlipTest(10.83, 100.0, 1.0),
        window=Window(2.0, 0.1),
        method="exact",
        whole_log=WholeLog(slip_episodes=True, fixes="given", records=False),
    )
    # Where a whole log identifies, a streaming estimator takes the stated defaults.
    assert (settings.wheels, settings.gyro, settings.bias_start) == (DEFAULT, DEFAULT_GYRO, 0.0)
    assert (settings.distance, settings.offset, settings.gating) == (Prior(), FixOffset(), Gate())
    estimator = PoseEstimator(R1)
    assert estimator.settings == settings
    assert estimator.config.gates[0] == pytest.approx(10.828, abs=1e-3)
    assert not estimator.config.estimate_scale
    assert not estimator.config.estimate_offset


@pytest.mark.parametrize(
    ("make", "error", "message"),
    [
        (lambda: Prior(0.0), ValueError, r"Prior\.start must be > 0"),
        (lambda: Prior(1.0, -0.1), ValueError, r"Prior\.sigma must be >= 0"),
        (lambda: Prior(1.0, 1e200), ValueError, r"Prior\.sigma 1e\+200 squares past"),
        (lambda: Prior(math.nan), ValueError, r"Prior\.start must be finite"),
        (lambda: Prior("1"), TypeError, r"Prior\.start"),
        (lambda: FixOffset(math.inf), ValueError, r"FixOffset\.rate must be finite"),
        (lambda: Gate(1.0), ValueError, r"Gate\.probability must be in \(0, 1\), got 1\.0"),
        (lambda: Gate(0.9, "keep"), ValueError, r"Gate\.outliers must be one of refuse, inflate"),
        (lambda: SlipTest(inflation=0.0), ValueError, r"SlipTest\.inflation must be > 0"),
        (lambda: Window(0.0), ValueError, r"Window\.history must be > 0"),
        (lambda: Window(1.0, -0.1), ValueError, r"Window\.ahead must be >= 0"),
        (lambda: Encoders(0), ValueError, r"Encoders\.ticks_per_revolution must be > 0"),
        (lambda: Encoders(counter_bits=70), ValueError, "counter_bits must be from 2 to 64"),
        (lambda: Encoders(max_wheel_speed=-1.0), ValueError, r"Encoders\.max_wheel_speed"),
        (lambda: WholeLog(records=1), TypeError, r"WholeLog\.records must be a bool"),
        (lambda: EstimatorSettings("compass"), ValueError, r"heading must be one of wheels"),
        (lambda: EstimatorSettings(wheel_noise=-1.0), ValueError, "wheel noise left"),
        (lambda: EstimatorSettings(bias=math.nan), ValueError, r"EstimatorSettings\.bias"),
        (lambda: EstimatorSettings(method="rk4"), ValueError, "method must be one of"),
        (lambda: EstimatorSettings(gate=0.99), TypeError, r"\.gate must be a Gate, got 0\.99"),
        (lambda: EstimatorSettings(slip=None), TypeError, r"\.slip must be a SlipTest, got None"),
        (lambda: EstimatorSettings(mounting=np.eye(2)), ValueError, "mounting must be a finite"),
        (lambda: EstimatorSettings(mounting=-np.eye(3)), ValueError, "not a rotation"),
        (lambda: PoseEstimator(R1, "wheels"), TypeError, "settings must be an EstimatorSettings"),
    ],
)
def test_a_bad_part_is_refused_by_its_name(make, error, message):
    with pytest.raises(error, match=message):
        make()


def test_replace_checks_again_and_keeps_the_original():
    settings = EstimatorSettings(wheel_noise=2e-4)
    assert settings.replace(heading="gyro").heading == "gyro"
    with pytest.raises(ValueError, match=r"Gate\.probability"):
        settings.replace(gate=Gate(2.0))
    with pytest.raises(TypeError, match="unexpected keyword argument 'noise'"):
        settings.replace(noise=G)
    assert settings == EstimatorSettings(wheel_noise=2e-4)
    with pytest.raises(dataclasses.FrozenInstanceError):
        settings.heading = "gyro"  # type: ignore[misc]


@given(
    st.sampled_from(["wheels", "gyro", "fused"]),
    st.floats(1e-9, 1e-2),
    st.floats(0.5, 2.0),
    st.floats(0.0, 0.5),
    st.floats(1e-6, 1 - 1e-9),
    st.sampled_from(["refuse", "inflate"]),
)
def test_the_core_is_built_from_the_settings_as_given(heading, k, start, sigma, gate, outliers):
    """Whatever valid settings: the core's numbers are the settings' own, so that one value
    and not a second spelling of it sets the estimator up."""
    settings = EstimatorSettings(
        heading, wheel_noise=k, turn_scale=Prior(start, sigma), gate=Gate(gate, outliers)
    )
    config = PoseEstimator(R2, settings).config
    assert (config.heading, config.k) == (heading, (k, k))
    assert (config.state[4], config.covariance[4 * 8 + 4]) == (start, sigma * sigma)
    assert (config.estimate_scale, config.inflate) == (sigma > 0, outliers == "inflate")
    assert config.estimate_bias == (heading == "fused")


def test_a_streaming_estimator_starts_from_a_whole_logs_identified_settings(monkeypatch):
    """``Estimate.used`` is the settings the pass ran with, what the log gave filled in (the
    gyro's noise and bias from its standing stretch, the wheels' noise against the gyro), with
    the caller's window: a streaming estimator started from it keeps 2 s of history, not the
    whole log, and ends where the whole log's filter does (but for what a stream given angles
    cannot know: how far the gyro's samples leave each turn open, left out here)."""
    monkeypatch.setattr(Gyro, "interpolation_variances", lambda self, at: np.zeros(len(at) - 1))
    t, inc, gyro, *_ = log(5, R2)
    estimate = estimate_trajectory(R2, t, inc, gyro=gyro, smooth=False)
    used = estimate.used
    assert used is not None
    assert used.gyro_noise is not None
    assert used.wheel_noise is not None
    assert used.bias == pytest.approx(0.01, abs=1e-3)
    assert used.window == Window()  # the caller's, not the pass's whole-log one: bounded
    streaming = PoseEstimator(R2, used, initial_time=0.0)
    turned = np.diff(gyro.angles(t))
    for k in range(len(inc)):
        streaming.update_increments(*inc[k], t[k + 1], gyro_angle=turned[k])
    np.testing.assert_allclose(streaming.state, estimate.states[-1], rtol=1e-9, atol=1e-11)


def test_the_command_line_builds_one_settings_value_and_restates_no_default(tmp_path):
    """With no option given, the command line's settings are the library's default but for
    what the log decides (the heading without a gyro) and the wheels' noise; --settings names
    any part or field, inline or in a TOML file, and what it does not name keeps its default."""
    from diffdrive.cli.estimate import estimator_settings, settings_changes
    from diffdrive.io import TableError

    assert estimator_settings(None, "given", True, {}) == EstimatorSettings()
    assert estimator_settings(None, "given", False, {}) == EstimatorSettings("wheels")
    given_k = estimator_settings(DEFAULT, "given", True, {})
    assert given_k == EstimatorSettings(wheel_noise=DEFAULT)
    changes = settings_changes(["gate.probability=0.9,whole_log.slip_episodes=false", "bias=0.01"])
    assert changes == {"gate.probability": 0.9, "whole_log.slip_episodes": False, "bias": 0.01}
    given_ = estimator_settings(DEFAULT, "identified", True, changes)
    assert given_.gate == Gate(0.9, "inflate")  # beside identified fixes, outliers inflated
    assert given_.whole_log == WholeLog(slip_episodes=False, fixes="identified")
    assert given_.bias == 0.01
    file = tmp_path / "estimator.toml"
    file.write_text('bias = 0.01\nheading = "gyro"\n[gate]\nprobability = 0.9\n')
    from_file = estimator_settings(None, "given", True, settings_changes([str(file)]))
    assert from_file == EstimatorSettings("gyro", bias=0.01, gate=Gate(0.9))
    file.write_text("[gate]\nprobability = 2\n")
    with pytest.raises(TableError, match=r"estimator\.toml: Gate\.probability must be in"):
        settings_changes([str(file)])
    with pytest.raises(ValueError, match=r"--settings: unknown setting 'gates\.probability'"):
        settings_changes(["gates.probability=0.9"])
    with pytest.raises(ValueError, match="give --fixes"):
        estimator_settings(DEFAULT, "given", True, {"whole_log.fixes": "identified"})
