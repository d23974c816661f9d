"""The OptiOdom run reader: columns, tick order, the ``Run`` it gives, and bad files named by
file and line."""

import numpy as np
import pytest

from data import data_folder
from diffdrive.io.optiodom import read_optiodom_run

GOOD = "0,0,0,0,0,0\n0.05,0.001,0.0,0.01,12,10\n0.1,0.002,0.0,0.02,13,-2\n"


def test_columns_and_the_right_then_left_order(tmp_path):
    path = tmp_path / "x_run-01.csv"
    path.write_text(GOOD)
    run = read_optiodom_run(path)
    np.testing.assert_array_equal(run.times, [0.0, 0.05, 0.1])
    np.testing.assert_array_equal(run.truth[-1], [0.002, 0.0, 0.02])
    # [left, right] counter readings: the file's per-cycle counts, right first, accumulated
    np.testing.assert_array_equal(run.wheels, [[0, 0], [10, 12], [8, 25]])
    assert (run.kind, run.ticks_per_revolution) == ("ticks", 43.7 * 64)
    assert run.where(2) == f"{path}:3"
    np.testing.assert_allclose(run.increments()[1], np.array([-2, 13]) * 2 * np.pi / (43.7 * 64))


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("0,0,0,0,0,0\n0.05,0,0,0,1\n", r"x_run-01\.csv:2: an OptiOdom line has 6 fields, got 5"),
        ("0,0,0,0,0,0\n0.05,0,zero,0,1,1\n", r"x_run-01\.csv:2: not a number"),
        ("0,0,0,0,0,0\n0.05,0,nan,0,1,1\n", r"x_run-01\.csv:2: not finite"),
        ("0,0,0,0,0,0\n0.05,0,0,0,1,1\n0.05,0,0,0,1,1\n", r"x_run-01\.csv:3: time 0\.05 does"),
        ("0,0,0,0,0,0\n0.05,0,0,0,1.5,1\n", r"x_run-01\.csv:2: ticks must be whole counts"),
        ("", r"x_run-01\.csv: a run needs at least 2 rows, got 0"),
    ],
)
def test_a_bad_file_is_named_with_its_line(tmp_path, text, message):
    path = tmp_path / "x_run-01.csv"
    path.write_text(text)
    with pytest.raises(ValueError, match=message):
        read_optiodom_run(path)


def test_every_shared_run_reads():
    runs = sorted(data_folder("optiodom-diffdrive").glob("*/*/*_run-*.csv"))
    assert len(runs) == 37
    for path in runs:
        run = read_optiodom_run(path)
        assert np.all(run.wheels[0] == 0)
        assert np.all(run.truth[0] == 0)
