"""The kernel's cache of machine code: written once per dtype, loaded by a fresh process
without numba, and compiled afresh when an entry is cut short, changed or made elsewhere."""

import json
import subprocess
import sys

import numpy as np
import pytest

import diffdrive as dd
from diffdrive.backends import simulate_kernel

pytest.importorskip("numba", reason="numba is part of the test extra")
llvm = pytest.importorskip("llvmlite.binding", reason="llvmlite comes with numba")

ROBOT = dd.DiffDrive(
    left_wheel_radius=0.05, right_wheel_radius=0.051, track_width=0.3, axle_offset=0.02
)
# A fresh process: simulate on the kernel, say whether numba was imported, and how far the
# poses are from the NumPy path's.
FRESH = """
import sys, numpy as np, diffdrive as dd
robot = dd.DiffDrive(left_wheel_radius=0.05, right_wheel_radius=0.051, track_width=0.3,
                     axle_offset=0.02)
wheels = np.random.default_rng(1).uniform(-20, 20, (3, 500, 2))
kernel = dd.simulate(robot, wheels, dt=0.01, backend="numba").poses
numpy = dd.simulate(robot, wheels, dt=0.01, backend="numpy").poses
print("numba" in sys.modules, float(np.abs(kernel - numpy).max()))
"""


def fresh(cache, **env) -> tuple[bool, float]:
    """Run ``FRESH`` with the cache folder ``cache``: (numba imported?, largest difference)."""
    import os

    environment = {**os.environ, "DIFFDRIVE_CACHE_DIR": str(cache), **env}
    done = subprocess.run(
        [sys.executable, "-c", FRESH], capture_output=True, text=True, env=environment, check=True
    )
    imported, difference = done.stdout.split()
    return imported == "True", float(difference)


def entries(cache):
    return sorted(cache.glob("simulate-float64-float64-float64-*.o"))


@pytest.mark.slow
@pytest.mark.skipif(not simulate_kernel._USES_CACHE, reason="no cache on this platform")
def test_a_fresh_process_loads_the_cached_kernel_without_numba(tmp_path, monkeypatch):
    assert fresh(tmp_path) == (True, pytest.approx(0.0, abs=1e-12))  # compiled: numba needed
    (code,) = entries(tmp_path)
    record = json.loads(code.with_suffix(".json").read_text())
    assert record["cpu"] == llvm.get_host_cpu_name()
    imported, difference = fresh(tmp_path)
    assert not imported
    assert difference < 1e-12
    monkeypatch.setenv("DIFFDRIVE_CACHE_DIR", str(tmp_path))
    assert simulate_kernel.cached(np.dtype("float64"))
    assert not simulate_kernel.cached(np.dtype("float32"))  # compiled for the dtypes used only


@pytest.mark.slow
@pytest.mark.skipif(not simulate_kernel._USES_CACHE, reason="no cache on this platform")
@pytest.mark.parametrize("damage", ["cut short", "another cpu", "no record"])
def test_a_damaged_or_foreign_entry_is_compiled_afresh(tmp_path, damage):
    fresh(tmp_path)
    (code,) = entries(tmp_path)
    record = code.with_suffix(".json")
    if damage == "cut short":
        code.write_bytes(code.read_bytes()[:100])
    elif damage == "another cpu":
        record.write_text(json.dumps({**json.loads(record.read_text()), "cpu": "pentium"}))
    else:
        record.unlink()
    imported, difference = fresh(tmp_path)
    assert imported  # numba compiled it again rather than load what was there
    assert difference < 1e-12
    assert not fresh(tmp_path)[0]  # and stored it whole


@pytest.mark.slow
def test_an_unwritable_cache_still_gives_the_kernel(tmp_path, monkeypatch):
    blocker = tmp_path / "a file"
    blocker.write_text("")
    monkeypatch.setenv("DIFFDRIVE_CACHE_DIR", str(blocker / "cache"))
    monkeypatch.setattr(simulate_kernel, "_loaded", {})
    wheels = np.random.default_rng(2).uniform(-20, 20, (200, 2))
    kernel = dd.simulate(ROBOT, wheels, dt=0.01, backend="numba").poses
    np.testing.assert_allclose(
        kernel, dd.simulate(ROBOT, wheels, dt=0.01, backend="numpy").poses, rtol=0, atol=1e-12
    )
    assert not (blocker / "cache").exists()


def test_runtime_helpers_become_traps_and_intrinsics_stay():
    ir = "\n".join(
        [
            "@PyExc_RuntimeError = external local_unnamed_addr global ptr",
            "declare void @numba_gil_ensure(ptr) local_unnamed_addr",
            "declare noalias ptr @helper(ptr noundef, i64, ...) #0",
            "declare double @llvm.cos.f64(double) #1",
            "define double @f(double %x) {",
            "  %c = call double @llvm.cos.f64(double %x)",
            "  ret double %c",
            "}",
            "attributes #0 = { nounwind }",
            "attributes #1 = { nounwind readnone }",
        ]
    )
    module = llvm.parse_assembly(simulate_kernel.trap_runtime_helpers(ir))
    module.verify()
    declared = sorted(f.name for f in module.functions if f.is_declaration)
    assert declared == ["llvm.cos.f64", "llvm.trap"]
    assert not any(g.is_declaration for g in module.global_variables)


def test_the_kernels_own_ir_needs_nothing_but_intrinsics():
    from diffdrive.backends.numba_simulate import kernel_ir

    ir, symbol = kernel_ir("float32", "float64", "float32")
    module = llvm.parse_assembly(simulate_kernel.trap_runtime_helpers(ir))
    assert not module.get_function(symbol).is_declaration
    assert all(f.name.startswith("llvm.") for f in module.functions if f.is_declaration)
    assert not any(g.is_declaration for g in module.global_variables)


def test_the_threads_follow_the_limit(monkeypatch):
    monkeypatch.delenv("NUMBA_NUM_THREADS", raising=False)
    monkeypatch.setattr(simulate_kernel, "_limit", [None])  # whatever a Dask test left
    everything = simulate_kernel.threads()
    simulate_kernel.set_threads(1)
    assert simulate_kernel.threads() == 1
    wheels = np.ones((3, 100, 2))
    one = dd.simulate(ROBOT, wheels, dt=0.01, backend="numba").poses
    simulate_kernel.set_threads(None)
    assert simulate_kernel.threads() == everything
    np.testing.assert_array_equal(dd.simulate(ROBOT, wheels, dt=0.01, backend="numba").poses, one)
    monkeypatch.setenv("NUMBA_NUM_THREADS", "1")
    assert simulate_kernel.threads() == 1
    monkeypatch.setenv("NUMBA_NUM_THREADS", "two")
    with pytest.raises(ValueError, match="NUMBA_NUM_THREADS must be a whole number from 1, got"):
        simulate_kernel.threads()
    with pytest.raises(ValueError, match="at least one thread, got 0"):
        simulate_kernel.set_threads(0)


@pytest.mark.parametrize("reason", ["not linux", "ir needs more"])
def test_without_the_cache_numbas_functions_run_the_same_tasks(monkeypatch, reason, tmp_path):
    monkeypatch.setenv("DIFFDRIVE_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(simulate_kernel, "_loaded", {})
    if reason == "not linux":
        monkeypatch.setattr(simulate_kernel, "_USES_CACHE", False)
    else:
        monkeypatch.setattr(simulate_kernel, "_compile", lambda *args: None)
    wheels = np.random.default_rng(3).uniform(-20, 20, (2, 300, 2))
    kernel = dd.simulate(ROBOT, wheels, dt=0.01, backend="numba").poses
    np.testing.assert_allclose(
        kernel, dd.simulate(ROBOT, wheels, dt=0.01, backend="numpy").poses, rtol=0, atol=1e-12
    )
    from diffdrive.backends.numba_simulate import run_tasks

    assert list(simulate_kernel._loaded.values()) == [run_tasks]
    assert not list(tmp_path.iterdir())  # nothing cached
