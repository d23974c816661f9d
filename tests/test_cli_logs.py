"""The command line on real-world logs: counter widths, time units, one velocity convention,
the formats every command reads and writes, and refusals that name the file and line."""

import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import diffdrive as dd
from data import data_folder
from diffdrive.cli import main
from diffdrive.io.trajectories import read_trajectory, write_trajectory

TICKS = 4096
ROBOT = ["--wheel-radius", "0.05", "--track-width", "0.3"]


def run(argv, capsys):
    code = main([str(a) for a in argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def encoder_log(path, bits=None, rows=200, rate=100.0, time_scale=1.0, offset=0):
    """A log of wheels at 5 and 6 rad/s read by counters of ``bits`` bits (true counts too)."""
    t = np.arange(rows) / rate
    counts = np.floor(np.column_stack([5.0 * t, 6.0 * t]) * TICKS / (2 * math.pi)).astype(int)
    counts += offset
    readings = counts % (2**bits) if bits else counts
    lines = [
        f"{float(tk * time_scale)!r},{left},{right}"
        for tk, (left, right) in zip(t, readings, strict=True)
    ]
    path.write_text("t,left_ticks,right_ticks\n" + "\n".join(lines) + "\n")
    return t, counts


def final_pose(path):
    _times, poses = read_trajectory(path)
    return poses[-1]


# -- counter widths ------------------------------------------------------------------------


def test_a_12_bit_log_read_as_16_bits_is_refused_and_read_right_as_12(tmp_path, capsys):
    log = tmp_path / "log.csv"
    encoder_log(log, bits=12, offset=4000)
    out = tmp_path / "odo.csv"
    common = ["odometry", log, *ROBOT, "--ticks-per-revolution", TICKS, "-o", out]
    code, _, err = run([*common, "--counter-bits", "16"], capsys)
    assert code == 1
    assert "log.csv:5: the counters jump by" in err
    assert "a 12-bit counter rolling over, read as 16-bit? Give --counter-bits 12" in err
    assert not out.exists()
    code, printed, _ = run([*common, "--counter-bits", "12"], capsys)
    assert code == 0
    plain = tmp_path / "plain.csv"
    encoder_log(plain, offset=4000)
    run(
        ["odometry", plain, *ROBOT, "--ticks-per-revolution", TICKS, "-o", tmp_path / "p.csv"],
        capsys,
    )
    np.testing.assert_allclose(final_pose(out), final_pose(tmp_path / "p.csv"), atol=1e-12)
    assert "largest wheel speed in the log: 6" in printed


def test_max_wheel_speed_refuses_the_row_and_names_its_line(tmp_path, capsys):
    log = tmp_path / "log.csv"
    encoder_log(log)
    argv = ["odometry", log, *ROBOT, "--ticks-per-revolution", TICKS, "-o", tmp_path / "o.csv"]
    code, _, err = run([*argv, "--max-wheel-speed", "5.5"], capsys)
    assert code == 1
    assert "log.csv:3: update_ticks:" in err
    assert "max_wheel_speed" in err


def test_a_wheel_speed_no_robot_drives_is_refused(tmp_path, capsys):
    log = tmp_path / "log.csv"
    log.write_text("t,left_angle,right_angle\n0,0,0\n0.01,0.1,0.1\n0.02,100,0.2\n")
    code, _, err = run(["odometry", log, *ROBOT, "-o", tmp_path / "o.csv"], capsys)
    assert code == 1
    assert "log.csv:4: the left wheel would turn at 9990 rad/s (500 m/s at its rim)" in err
    code, _, err = run(["simulate", log, *ROBOT, "-o", tmp_path / "s.csv"], capsys)
    assert code == 1
    assert "500 m/s at its rim" in err
    code, out, _ = run(
        ["odometry", log, *ROBOT, "--max-wheel-speed", "1e5", "-o", tmp_path / "o.csv"], capsys
    )
    assert code == 0
    assert "largest wheel speed in the log: 9990 rad/s (500 m/s at the rim), left wheel" in out


def test_64_bit_counters_are_read_exactly(tmp_path, capsys):
    log = tmp_path / "log.csv"
    rows = [
        f"{k * 0.01!r},{2**60 + 10 * k},{2**64 - 5 + 10 * k - (2**64 if k > 0 else 0)}"
        for k in range(5)
    ]
    log.write_text("t,left_ticks,right_ticks\n" + "\n".join(rows) + "\n")
    out = tmp_path / "o.csv"
    argv = ["odometry", log, *ROBOT, "--ticks-per-revolution", TICKS, "--counter-bits", "64"]
    code, _, err = run([*argv, "-o", out], capsys)
    assert code == 0, err
    # 10 counts a row on both wheels: straight ahead
    x = 4 * 10 * 2 * math.pi / TICKS * 0.05
    np.testing.assert_allclose(final_pose(out), [x, 0.0, 0.0], atol=1e-12)


def test_twist_and_covariance_columns(tmp_path, capsys):
    log = tmp_path / "log.csv"
    encoder_log(log, rows=50)
    out = tmp_path / "o.csv"
    argv = [
        "odometry",
        log,
        *ROBOT,
        "--ticks-per-revolution",
        TICKS,
        "--k-left",
        "1e-4",
        "--k-right",
        "1e-4",
        "--twist",
        "--covariance",
        "-o",
        out,
    ]
    assert run(argv, capsys)[0] == 0
    header = out.read_text().splitlines()[0].split(",")
    assert header == [
        "t",
        "x",
        "y",
        "theta",
        "vx",
        "vy",
        "omega",
        "cov_xx",
        "cov_xy",
        "cov_xtheta",
        "cov_yy",
        "cov_ytheta",
        "cov_thetatheta",
        "cov_vxvx",
        "cov_vxvy",
        "cov_vxomega",
        "cov_vyvy",
        "cov_vyomega",
        "cov_omegaomega",
    ]
    table = np.genfromtxt(out, delimiter=",", names=True)
    assert table["vx"][0] == table["vx"][1]  # the first row: the first interval's twist
    assert table["vx"][-1] == pytest.approx(0.05 * 5.5, rel=0.02)
    assert table["cov_xx"][0] == 0.0
    assert table["cov_yy"][-1] > 0.0
    assert np.all(table["cov_vxvx"] > 0.0)


# -- time units ----------------------------------------------------------------------------


@pytest.mark.parametrize(("unit", "scale"), [("ns", 1e9), ("ms", 1e3), ("us", 1e6)])
def test_a_log_in_other_time_units(tmp_path, capsys, unit, scale):
    seconds, other = tmp_path / "s.csv", tmp_path / f"{unit}.csv"
    encoder_log(seconds)
    encoder_log(other, time_scale=scale)
    epoch = tmp_path / "epoch.csv"  # stamps since 1970, as ROS writes them
    encoder_log(epoch, time_scale=scale)
    text = epoch.read_text().splitlines()
    rows = [
        f"{float(line.split(',')[0]) + 1.7e9 * scale!r},{line.split(',', 1)[1]}"
        for line in text[1:]
    ]
    epoch.write_text(text[0] + "\n" + "\n".join(rows) + "\n")
    base = ["odometry", *ROBOT, "--ticks-per-revolution", TICKS]
    for path in (other, epoch):
        code, _, err = run([*base, path, "-o", tmp_path / "x.csv"], capsys)
        assert code == 1
        assert "is not in seconds" in err
        assert f"--time-unit {unit}" in err
    code, _, err = run([*base, other, "--time-unit", unit, "-o", tmp_path / "a.csv"], capsys)
    assert code == 0, err
    run([*base, seconds, "-o", tmp_path / "b.csv"], capsys)
    a, b = read_trajectory(tmp_path / "a.csv"), read_trajectory(tmp_path / "b.csv")
    np.testing.assert_allclose(a[0], b[0], rtol=1e-12)
    np.testing.assert_allclose(a[1], b[1], atol=1e-9)


@pytest.mark.parametrize("kind", ["velocity", "ticks"])
def test_a_200_hz_log_in_milliseconds_is_not_read_as_seconds(tmp_path, capsys, kind):
    """Rows 5 ms apart read as 5 s: 530 turns over "9995 s" (velocities), or the right path
    with times 1000 times too long (ticks), both with exit 0. A wheel log of 100 rows or more
    a second or more apart is refused with the unit named; a short hand-written history at
    1 s a row still reads as seconds."""
    log, short = tmp_path / f"{kind}.csv", tmp_path / "short.csv"
    if kind == "velocity":
        rows = [f"{5 * k},8.0,10.0" for k in range(2000)]
        header = "t,left_velocity,right_velocity"
        extra = []
    else:
        rows = [f"{5 * k},{8 * k},{10 * k}" for k in range(2000)]
        header = "t,left_ticks,right_ticks"
        extra = ["--ticks-per-revolution", TICKS]
    log.write_text(header + "\n" + "\n".join(rows) + "\n")
    short.write_text(header + "\n" + "\n".join(rows[:20]) + "\n")
    for command in ("simulate", "odometry"):
        code, _, err = run([command, log, *ROBOT, *extra, "-o", tmp_path / "x.csv"], capsys)
        assert code == 1, command
        assert "is not in seconds: 2000 rows 5 apart" in err
        assert "a 200 Hz log in ms? Give the time unit (--time-unit ms)" in err
        assert not (tmp_path / "x.csv").exists()
        argv = [command, log, *ROBOT, *extra, "--time-unit", "ms", "-o", tmp_path / "ms.csv"]
        assert run(argv, capsys)[0] == 0
        assert read_trajectory(tmp_path / "ms.csv")[0][-1] == pytest.approx(9.995)
        argv = [command, short, *ROBOT, *extra, "-o", tmp_path / "s.csv"]
        assert run(argv, capsys)[0] == 0


# -- one convention for velocities -------------------------------------------------------------


def test_simulate_and_odometry_agree_on_a_velocity_log(tmp_path, capsys):
    log = tmp_path / "v.csv"
    log.write_text("t,left_velocity,right_velocity\n0,10,10\n0.5,5,12\n1.0,7,3\n")
    for command in ("simulate", "odometry"):
        code, out, err = run([command, log, "-o", tmp_path / f"{command}.csv"], capsys)
        assert code == 0, err
        assert "robot: the built-in robot (42 mm wheels, track 0.2 m; assumed" in out
        _, out, _ = run([command, log, *ROBOT, "-o", tmp_path / "told.csv"], capsys)
        assert "robot:" not in out
    simulated = read_trajectory(tmp_path / "simulate.csv")[1]
    odometry = read_trajectory(tmp_path / "odometry.csv")[1]
    np.testing.assert_allclose(simulated, odometry, atol=1e-12)
    robot = dd.demo.example_robot()
    expected = dd.simulate(robot, np.array([[10.0, 10.0], [5.0, 12.0]]), dt=0.5).poses
    np.testing.assert_allclose(simulated, expected, atol=1e-12)  # held until the next row


def test_odometry_and_evaluate_give_the_built_in_example_the_same_error(
    tmp_path, capsys, monkeypatch
):
    monkeypatch.chdir(tmp_path)
    _, out, _ = run(["odometry"], capsys)
    said = float(out.split("position error max ")[1].split(" m")[0])
    _, out, _ = run(["evaluate", "--json"], capsys)
    assert json.loads(out)["max_position_error_m"] == pytest.approx(said, abs=5e-5)


# -- files that fit together -----------------------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize("suffix", ["tum", "jsonl", "csv"])
def test_what_simulate_writes_evaluate_and_plot_read(tmp_path, capsys, suffix):
    written = tmp_path / f"trajectory.{suffix}"
    assert run(["simulate", "-o", written, "-q"], capsys)[0] == 0
    truth = tmp_path / "truth.csv"
    run(["simulate", "-o", truth, "-q"], capsys)
    code, out, err = run(["evaluate", written, "--truth", truth, "--json"], capsys)
    assert code == 0, err
    assert json.loads(out)["ate_m"] < 1e-9
    code, _, err = run(["plot", written, "--truth", truth, "-o", tmp_path / "p.png"], capsys)
    assert code == 0, err


def test_odometry_reads_the_optiodom_run_files_calibrate_reads(tmp_path, capsys):
    run_file = data_folder("optiodom-diffdrive") / "square/230620202042/230620202042_run-01.csv"
    code, out, err = run(
        ["odometry", run_file, "--method", "rk2", "-o", tmp_path / "o.csv"], capsys
    )
    assert code == 0, err
    # The authors' nominal robot is the example robot: their figure, 0.0130 m (runs_index.csv)
    assert "position error max 0.0130 m" in out


@pytest.mark.slow
@pytest.mark.parametrize(
    ("text", "name"),
    [
        ("\ufefft,left_angle,right_angle\n0,0,0\n1,1,2\n", "bom"),
        ("t;left_angle;right_angle\n0;0;0\n1;1,0;2,0\n", "semicolon, decimal comma"),
        ("t\tleft_angle\tright_angle\n0\t0\t0\n1\t1\t2\n", "tab"),
        ("# a comment\nt left_angle  right_angle\n0 0 0\n1   1 2\n", "spaces"),
    ],
)
def test_spreadsheet_dialects(tmp_path, capsys, text, name):
    log = tmp_path / "log.csv"
    log.write_text(text, encoding="utf-8")
    code, _, err = run(["simulate", log, "-o", tmp_path / "o.csv"], capsys)
    assert code == 0, (name, err)
    twist = dd.demo.example_robot().to_twist((1.0, 2.0))
    np.testing.assert_allclose(final_pose(tmp_path / "o.csv"), dd.se2.exp(twist).to_array())


def test_text_that_is_not_utf8_is_named(tmp_path, capsys):
    log = tmp_path / "log.csv"
    log.write_bytes("t,left_angle,right_angle\n0,0,0\n1,1,2 # \u00e9\n".encode("latin-1"))
    code, _, err = run(["simulate", log], capsys)
    assert code == 1
    assert "log.csv:3: not UTF-8 text" in err


def test_many_robots_are_written_and_plotted(tmp_path, capsys):
    robot = dd.DiffDrive(wheel_radius=0.05, track_width=0.3)
    wheels = np.random.default_rng(1).normal(8, 2, (5, 100, 2))
    trajectory = dd.simulate(robot, wheels, dt=0.02)
    for suffix in ("csv", "jsonl"):
        path = tmp_path / f"many.{suffix}"
        write_trajectory(path, trajectory.times, trajectory.poses, suffix)
        _times, poses = read_trajectory(path)
        np.testing.assert_array_equal(poses, trajectory.poses)
    written = write_trajectory(tmp_path / "many.tum", trajectory.times, trajectory.poses, "tum")
    assert [p.name for p in written] == [f"many_{k}.tum" for k in range(5)]
    np.testing.assert_allclose(read_trajectory(written[3])[1], trajectory.poses[3], atol=1e-12)
    code, _, err = run(["plot", tmp_path / "many.csv", "-o", tmp_path / "fan.png"], capsys)
    assert code == 0, err
    assert (tmp_path / "fan.png").stat().st_size > 10_000


def test_a_missing_output_folder_is_named(tmp_path, capsys):
    code, _, err = run(["simulate", "-o", tmp_path / "missing" / "x.csv"], capsys)
    assert code == 1
    assert f"the folder {tmp_path / 'missing'} does not exist" in err
    assert ".x." not in err  # no temporary file name


def test_negative_numbers_in_exponent_form(capsys):
    code, out, _ = run(["fk", "1", "-1e-3", "--json"], capsys)
    assert code == 0
    assert json.loads(out)["vx"] == pytest.approx(0.042 * (1 - 1e-3) / 2)


def test_half_track_from_the_command_line(capsys):
    _, full, _ = run(["fk", "8", "10", "--wheel-radius", "0.05", "--track-width", "0.3"], capsys)
    _, half, _ = run(["fk", "8", "10", "--wheel-radius", "0.05", "--half-track", "0.15"], capsys)
    assert full == half


def test_flags_that_set_the_same_length_are_refused_and_override_a_file_alike(tmp_path, capsys):
    """--track-width 0.5 --half-track 0.15 used 0.3, silently; --wheel-radius against a file's
    left and right radii was refused, with the blame on the file."""
    argv = ["fk", "8", "10", "--wheel-radius", "0.05", "--track-width", "0.5"]
    code, _, err = run([*argv, "--robot", "half_track=0.15"], capsys)
    assert code == 1
    assert "--track-width and --robot half_track both given: they set the same length" in err
    code, _, err = run([*argv, "--half-track", "0.15"], capsys)  # the spelling before 0.9
    assert code == 1
    assert "--track-width and --robot half_track both given: they set the same length" in err
    code, _, err = run([*argv, "--robot", "left_wheel_radius=0.05"], capsys)
    assert code == 1
    assert "--wheel-radius and --robot left_wheel_radius both given" in err
    robot = tmp_path / "robot.toml"
    robot.write_text("left_wheel_radius = 0.04\nright_wheel_radius = 0.06\nhalf_track = 0.1\n")

    def fk(*flags):
        code, out, err = run(["fk", "8", "10", "--robot", robot, *flags, "--json"], capsys)
        assert code == 0, err
        return json.loads(out)

    plain = dd.DiffDrive(0.05, 0.5).to_twist((8, 10))
    overridden = fk("--wheel-radius", "0.05", "--track-width", "0.5")
    assert overridden["vx"] == pytest.approx(plain.vx)
    assert overridden["omega"] == pytest.approx(plain.omega)
    one = dd.DiffDrive(left_wheel_radius=0.05, right_wheel_radius=0.06, half_track=0.1)
    assert fk("--robot", "left_wheel_radius=0.05")["omega"] == pytest.approx(
        one.to_twist((8, 10)).omega
    )
    robot.write_text("wheel_radius = 0.04\ntrack_width = 0.2\n")
    kept = dd.DiffDrive(left_wheel_radius=0.05, right_wheel_radius=0.04, track_width=0.2)
    assert fk("--robot", "left_wheel_radius=0.05")["omega"] == pytest.approx(
        kept.to_twist((8, 10)).omega
    )
    assert fk("--left-wheel-radius", "0.05")["omega"] == pytest.approx(kept.to_twist((8, 10)).omega)


@pytest.mark.parametrize("command", ["simulate", "odometry"])
def test_both_help_texts_state_the_velocity_convention(capsys, command):
    with pytest.raises(SystemExit):
        main([command, "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "rad/s, each held from its row's time until the next row's" in text
    assert "the FULL distance between the wheels' contact points" in text


def test_a_step_too_small_to_hold_in_memory_is_refused(capsys):
    code, _, err = run(["simulate", "--dt", "1e-9"], capsys)
    assert code == 1
    assert "GiB of poses" in err


# -- the fast paths read and write exactly what the careful ones do ----------------------------


@given(
    st.lists(
        st.tuples(
            st.floats(0.001, 5.0),
            st.integers(-(2**62), 2**62),
            st.floats(-1e6, 1e6, allow_subnormal=False),
        ),
        min_size=1,
        max_size=30,
    ),
    st.sampled_from(["", "\n", "\n\n"]),
)
@settings(max_examples=60)
def test_numpys_csv_parser_reads_what_the_cell_by_cell_reader_reads(rows, ending):
    import tempfile
    from unittest import mock

    from diffdrive.io import tables as files

    steps = np.cumsum([r[0] for r in rows])
    text = "t,left_ticks,x\n" + "\n".join(
        f"{t!r},{k},{x!r}" for t, (_, k, x) in zip(steps.tolist(), rows, strict=True)
    )
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "log.csv"
        path.write_text(text + ending)
        fast = files.read_table(path, ["t", "left_ticks", "x"], integers=["left_ticks"])
        with mock.patch.object(files, "_read_plain_csv", return_value=None):
            slow = files.read_table(path, ["t", "left_ticks", "x"], integers=["left_ticks"])
    for name in ("t", "left_ticks", "x"):
        assert fast[name].dtype == slow[name].dtype
        np.testing.assert_array_equal(fast[name], slow[name])
    np.testing.assert_array_equal(fast.lines, slow.lines)


def test_written_floats_read_back_exactly_with_or_without_orjson(tmp_path, monkeypatch):
    import sys

    rng = np.random.default_rng(2)
    poses = rng.normal(size=(500, 3)) * 10.0 ** rng.integers(-20, 20, (500, 3))
    times = np.cumsum(rng.uniform(0.001, 1, 500))
    columns = {"extra": np.where(np.arange(500) % 7 == 0, np.nan, times)}
    write_trajectory(tmp_path / "a.csv", times, poses, "csv", columns)
    monkeypatch.setitem(sys.modules, "orjson", None)
    write_trajectory(tmp_path / "b.csv", times, poses, "csv", columns)
    for name in ("a.csv", "b.csv"):
        back = np.genfromtxt(tmp_path / name, delimiter=",", names=True)
        np.testing.assert_array_equal(back["t"], times)
        np.testing.assert_array_equal(np.column_stack([back["x"], back["y"], back["theta"]]), poses)
        assert np.isnan(back["extra"][0])


def test_update_arrays_equals_one_update_at_a_time_and_names_the_refused_row():
    robot = dd.DiffDrive(left_wheel_radius=0.05, right_wheel_radius=0.051, track_width=0.3)
    rng = np.random.default_rng(4)
    counts = np.cumsum(rng.integers(-20, 60, (300, 2)), axis=0) % 4096
    times = np.cumsum(rng.uniform(0.005, 0.02, 300))
    one = dd.Odometry(robot, ticks_per_revolution=4096, counter_bits=12, wheel_noise=1e-4)
    many = dd.Odometry(robot, ticks_per_revolution=4096, counter_bits=12, wheel_noise=1e-4)
    expected = []
    for (left, right), t in zip(counts.tolist(), times.tolist(), strict=True):
        one.update_ticks(left, right, t)
        expected.append((*one.pose.to_array(), *one.covariance.ravel()))
    poses, covariances = many.update_arrays("ticks", counts[:, 0], counts[:, 1], times, True)
    np.testing.assert_array_equal(np.column_stack([poses, covariances.reshape(-1, 9)]), expected)
    bad_times = times.copy()
    bad_times[150] = bad_times[149]  # time stands still while the wheels move
    fresh = dd.Odometry(robot, ticks_per_revolution=4096, counter_bits=12)
    refused = dd.estimation.RefusedUpdateError
    with pytest.raises(refused, match="row 150: update_ticks: time") as err:
        fresh.update_arrays("ticks", counts[:, 0], counts[:, 1], bad_times)
    assert err.value.row == 150
    np.testing.assert_array_equal(fresh.pose.to_array(), expected[149][:3])
