"""Every benchmark runs and prints what its record keeps: the scripts whose records hold the
figures the guides quote (``benchmarks/records/``) are run here on sizes too small to time
anything, so that one that breaks (as ``bench_logs.py`` did, on a subpackage ``import
diffdrive`` leaves unloaded) fails the suite, not the next person who records it, and one that
prints something its record does not show (a line changed, added or renamed) asks for its
record to be taken again. Their figures are their records', taken on the machine and date each
record names; timings are not for unit tests."""

import re
import sys
from pathlib import Path

import pytest

from firmware import require_cross
from processes import run_bounded
from records import HEADER, NUMBER, record

ROOT = Path(__file__).resolve().parents[1]

# Each benchmark with the smallest sizes it takes (its defaults are what its record used).
SMALL = {
    # the extension before and after: here HEAD twice (a clone and a build each)
    "bench_c_core": [
        "--seconds",
        "20",
        "--rounds",
        "1",
        "--against",
        "HEAD",
        "--updates",
        "1000",
        "--log",
        "500",
    ],
    "bench_estimation": ["--seeds", "30", "--coverage-seeds", "1", "--repeats", "1"],
    "bench_fixes": ["--seeds", "1"],
    "bench_import": ["--runs", "1"],
    "bench_logs": ["--rows", "1000", "--messages", "100", "--repeats", "1"],
    "bench_montecarlo": ["--robots", "100", "--steps", "10", "--repeats", "1"],
    # PyTorch's and JAX's cycles: tests/test_mppi.py runs them.
    "bench_mppi": [
        "--runs",
        "1",
        "--compare",
        "1",
        "--paths",
        "1",
        "--repeats",
        "1",
        "--other-paths",
        "1",
        "--other-runs",
        "1",
        "--libraries",
        "numba",
        "numpy",
    ],
    "bench_noise_model": ["--seeds", "1"],
    "bench_odometry": ["--repeats", "1", "--updates", "100"],
    "bench_planning": ["--paths", "10", "--repeats", "1"],
    "bench_reference_calibration": [
        "--seeds",
        "1",
        "--noise-seeds",
        "1",
        "--track-seeds",
        "1",
        "--log-seconds",
        "120",
        "--repeats",
        "1",
    ],
    "bench_sensors": ["--robots", "10", "--steps", "10", "--repeats", "1"],
    "bench_simulate": ["--repeats", "1", "--quick"],
    "bench_slip_detection": ["--robots", "1"],
    "bench_smoother": ["--intervals", "1000", "--twin-intervals", "100", "--repeats", "1"],
}


def test_every_benchmark_is_in_the_table():
    scripts = sorted(path.stem for path in (ROOT / "benchmarks").glob("bench_*.py"))
    assert scripts == sorted(SMALL)


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(SMALL))
def test_the_benchmark_runs_on_small_sizes(name):
    if name == "bench_c_core":
        require_cross("bench_c_core's run on small sizes")
    # Bounded by processor time, not the wall clock: a busy machine only slows it.
    run = run_bounded(
        [sys.executable, str(ROOT / "benchmarks" / f"{name}.py"), *SMALL[name]], cwd=ROOT
    )
    assert run.returncode == 0, run.stderr[-3000:]
    shapes = {_shape(line) for line in record("benchmarks", name)}
    printed = [line for line in run.stdout.splitlines() if line.strip()]
    assert printed, f"{name} printed nothing"
    # A peer the record had and this clone lacks (make bench installs them) is left out,
    # as the script says: its line is not a change of the script's.
    printed = [line for line in printed if not line.startswith("not installed, left out:")]
    new = [line for line in printed if _shape(line) not in shapes]
    assert new == [], (
        f"{name} prints lines its record does not show; take it again with python "
        f"benchmarks/record.py benchmarks/{name}.py and quote the new figures: {new}"
    )


def _shape(line: str) -> str:
    """A printed line with its numbers left out, and a run of numbers (as many as there are
    groups of seeds) as one: what the sizes and the machine do not change."""
    numbered = NUMBER.sub("#", line)
    return " ".join(re.sub(r"#(?:[%x]?[,;/ ]+#)*[%x]?", "#", numbered).split())


def test_a_record_says_when_and_where_and_a_failed_run_keeps_the_last(tmp_path):
    """``benchmarks/record.py`` writes what a script printed under a line with the command,
    the date and the machine; a script that fails leaves the record it had."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        from record import record as take
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))
    script = tmp_path / "examples" / "hello.py"
    script.parent.mkdir()
    script.write_text("import sys\nprint('error 0.0907 m over', sys.argv[1:])\n")
    written = take(script, ["--seeds", "3"])
    lines = written.read_text().splitlines()
    assert re.fullmatch(HEADER, lines[0]), lines[0]
    assert lines[0].startswith("# python examples/hello.py --seeds 3: "), lines[0]
    assert lines[1:] == ["error 0.0907 m over ['--seeds', '3']"]
    script.write_text("raise SystemExit(3)\n")
    with pytest.raises(SystemExit, match="failed \\(exit 3\\); its record is unchanged"):
        take(script, [])
    assert written.read_text().splitlines() == lines
