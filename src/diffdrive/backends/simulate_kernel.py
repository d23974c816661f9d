"""``simulate``'s compiled kernel as machine code cached on disk, loaded without numba.

numba compiles the kernel (``numba_simulate.kernel_ir``) once for each combination of dtypes
that is used, and only then. Its LLVM IR declares a few helpers of numba's runtime (raising a
Python exception, freeing reference-counted memory) that the kernel never reaches: it raises
nothing and allocates nothing. Those become traps, the IR becomes an object file for this CPU,
and the object file is stored with a digest in the cache folder. A fresh process loads it with
llvmlite's MCJIT (numba's own code generator, about 0.1 s with llvmlite's import) instead of
importing numba (about 0.45 s here) and setting up its compiler (about 0.6 s more).

The cache folder is ``DIFFDRIVE_CACHE_DIR``, else ``__pycache__`` beside this module when it
can be written, else ``~/.cache/diffdrive``. A file is used only when its name matches the
kernel's sources, numba's and llvmlite's versions and the dtypes, and its record matches this
CPU and the file's digest; anything else is compiled afresh. The cache is used on Linux, where
it was built and tested (the code needs libm from the process); elsewhere numba's own
functions run the same tasks.

The tasks (``numba_simulate.run_tasks``: a robot, or a chunk of one, in up to three passes)
are shared out over threads in contiguous runs; every call releases the GIL.
"""

from __future__ import annotations

import ctypes
import functools
import hashlib
import importlib.metadata
import json
import os
import re
import sys
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from diffdrive import _step
from diffdrive.integrate import Method
from diffdrive.model import DiffDrive, geometry_of

__all__ = [
    "cached",
    "chunk_count",
    "idle_threads",
    "integrate_history",
    "loaded",
    "set_threads",
    "threads",
]

# Fewer steps than this per chunk and the three passes cost more than they save.
_MIN_CHUNK = 1 << 14
# What the machine code comes from: the kernel, its step, and how the cache is written.
_SOURCES = ("numba_simulate.py", "../_step.py", "simulate_kernel.py")
_USES_CACHE = sys.platform.startswith("linux")
# numba_simulate.kernel_ir's C signature: "p" a pointer, "i" an int64 (a count or a flag).
_C_SIGNATURE = tuple(
    ctypes.c_void_p if kind == "p" else ctypes.c_int64 for kind in "ipiipiiippiiippiipii"
)
_DECLARATION = re.compile(
    r"^declare (?P<head>.*?)@(?P<name>[-\w.$]+|\"[^\"]+\")\((?P<arguments>.*)\)(?P<tail>[^()]*)$",
    re.MULTILINE,
)
_EXTERNAL_GLOBAL = re.compile(
    r"^(?P<name>@\S+) = external (?P<kind>.*?global) (?P<type>.+)$", re.MULTILINE
)

_limit: list[int | None] = [None]  # set_threads'
_loaded: dict[tuple[str, str, str], Callable[..., None]] = {}
_engines: list[Any] = []  # the MCJIT engines that own the loaded code: kept for the process
_lock = threading.Lock()


def threads() -> int:
    """The threads the kernel runs on: the CPUs this process may use, at most ``set_threads``'
    limit or ``NUMBA_NUM_THREADS`` (numba's own setting, which its kernel followed before)."""
    affinity = getattr(os, "sched_getaffinity", None)
    cpus = len(affinity(0)) if affinity else os.cpu_count() or 1
    setting = os.environ.get("NUMBA_NUM_THREADS") or str(cpus)
    if not setting.isdigit() or int(setting) < 1:
        raise ValueError(f"NUMBA_NUM_THREADS must be a whole number from 1, got {setting!r}")
    return max(1, min(cpus, _limit[0] or int(setting)))


def set_threads(count: int | None) -> None:
    """Run the kernel on at most ``count`` threads (None: as many as there are CPUs); a Dask
    worker sets one, so that its processes share out the cores."""
    if count is not None and count < 1:
        raise ValueError(f"the kernel needs at least one thread, got {count}")
    _limit[0] = count


def chunk_count(robots: int, steps: int, dtype: np.dtype, threads: int) -> int:
    """How many chunks to cut each robot's steps into so that every thread has work."""
    if dtype != np.float64 or robots >= threads:
        return 1
    return max(1, min(-(-threads // robots), steps // _MIN_CHUNK))


def idle_threads(threads: int) -> int:
    """Of ``threads``, those whose CPUs no other task is running on now (Linux's count of
    runnable tasks; all of them where it cannot be read). A robot's steps are cut into
    chunks only for these: the chunks' passes wait for the slowest, so a chunk on a CPU that
    another process holds slows the whole robot (to 0.1-0.3x a plain loop, measured), where
    one thread keeps a loop's pace."""
    running = _running_tasks()
    if running is None:
        return threads
    others = running - _own_running()
    return max(1, min(threads, threads - others))


def _running_tasks() -> int | None:
    """The tasks running or ready to run now, this thread among them (``/proc/loadavg``'s
    fourth field), or None where there is no such file."""
    try:
        with open("/proc/loadavg", encoding="ascii") as file:
            return int(file.read().split()[3].split("/")[0])
    except (OSError, ValueError, IndexError):
        return None


def _own_running() -> int:
    """This process's threads running or ready to run now (this one at least): a parallel
    pool's threads spin a while after each pass (numba's OpenMP layer), and counted as other
    tasks they would halve the next pass's threads."""
    # os, not pathlib: MPPI's cycles count with it, and pathlib's glob took 60 of its 75 us.
    count = 0
    try:
        tasks = os.listdir("/proc/self/task")
    except OSError:
        return 1
    for task in tasks:
        try:
            with open(f"/proc/self/task/{task}/stat", "rb") as file:
                state = file.read().rsplit(b")", 1)[1].split()[0]
        except (OSError, IndexError):
            continue  # a thread that ended meanwhile
        count += state == b"R"
    return max(1, count)


def integrate_history(
    robot: DiffDrive,
    history: np.ndarray,
    times: np.ndarray,
    angles: bool,
    start: np.ndarray,
    method: Method,
    out: np.ndarray,
    chunks: int | None = None,
) -> None:
    """Integrate N robots' driving histories into ``out`` ``(N, T+1, 3)``.

    ``history`` is ``(N or 1, T+1, 2)`` wheel angles (rad) when ``angles``, else
    ``(N or 1, T, 2)`` wheel velocities (rad/s) held over each step; ``times`` is
    ``(N or 1, T+1)`` (s) and ``start`` ``(N, 3)``. A first axis of 1 is shared by all robots.
    ``chunks`` (default: ``chunk_count``'s) cuts each robot's steps for the threads.
    """
    if not out.flags.c_contiguous:
        raise ValueError("the kernel writes C-contiguous poses only")
    robots, steps = out.shape[0], out.shape[1] - 1
    workers = threads()
    if chunks is None:
        if robots < workers:  # a few robots, each cut for the threads: only idle ones
            workers = idle_threads(workers)
        chunks = chunk_count(robots, steps, out.dtype, workers)
    tasks = robots * chunks
    # C-contiguous arrays only: the kernel indexes them as such.
    history, times = np.ascontiguousarray(history), np.ascontiguousarray(times)
    start = np.ascontiguousarray(start, dtype=np.float64)
    geometry = np.array(geometry_of(robot))
    turns, ends = np.zeros(tasks), np.zeros((tasks, 2))
    kernel = _kernel(history.dtype, times.dtype, out.dtype)
    weight, chord = _step.method_flags(method)
    midpoint = weight != 0.0  # the kernel turns the move by half the step's turn, or not

    inputs = (history, times, angles, start, geometry, midpoint, chord, chunks, turns, out, ends)

    def run(stage: int, first: int, stop: int) -> None:
        kernel(stage, inputs, first, stop)

    for stage in (0, 1, 2) if chunks > 1 else (1,):  # each pass waits for the one before
        _share_out(min(workers, tasks), tasks, functools.partial(run, stage))


def _share_out(runs: int, tasks: int, work: Callable[[int, int], None]) -> None:
    """``work(first, stop)`` over tasks ``0:tasks`` in ``runs`` contiguous runs, on as many
    threads when there are several."""
    if runs <= 1:
        work(0, tasks)
        return
    bounds = [tasks * k // runs for k in range(runs + 1)]
    with ThreadPoolExecutor(runs) as pool:
        for done in [pool.submit(work, bounds[k], bounds[k + 1]) for k in range(runs)]:
            done.result()  # raises what the run raised


def loaded(dtype: np.dtype) -> bool:
    """Whether a kernel writing poses of ``dtype`` is in this process already."""
    return any(key[2] == np.dtype(dtype).name for key in _loaded)


def cached(dtype: np.dtype) -> bool:
    """Whether a kernel writing poses of ``dtype`` is in the cache folder (by its name alone,
    without loading llvmlite or numba)."""
    if not _USES_CACHE:
        return False
    pattern = f"simulate-*-{np.dtype(dtype).name}-{_digest()}.o"
    return any(folder.is_dir() and any(folder.glob(pattern)) for folder in _folders())


def _kernel(values: np.dtype, times: np.dtype, poses: np.dtype) -> Callable[..., None]:
    """The kernel for these dtypes: loaded, from the cache or compiled into it."""
    key = (values.name, times.name, poses.name)
    if not set(key) <= {"float32", "float64"}:
        raise ValueError(f"the kernel takes float32 or float64 arrays, got {', '.join(key)}")
    with _lock:
        if key not in _loaded:
            _loaded[key] = _load_or_compile(key) if _USES_CACHE else _numba_tasks()
    return _loaded[key]


def _numba_tasks() -> Callable[..., None]:
    from diffdrive.backends.numba_simulate import run_tasks

    return run_tasks


def _load_or_compile(key: tuple[str, str, str]) -> Callable[..., None]:
    import llvmlite.binding as llvm

    llvm.initialize_native_target()
    llvm.initialize_native_asmprinter()
    cpu = {"cpu": llvm.get_host_cpu_name(), "features": llvm.get_host_cpu_features().flatten()}
    machine = llvm.Target.from_default_triple().create_target_machine(
        **cpu, opt=3, codemodel="jitdefault"
    )
    name = f"simulate-{'-'.join(key)}-{_digest()}"
    for folder in _folders():
        found = _read(folder / f"{name}.o", folder / f"{name}.json", cpu)
        if found is not None:
            return _link(llvm, machine, *found)
    compiled = _compile(llvm, machine, key)
    if compiled is None:  # numba's IR needs more than libm: run numba's functions instead
        return _numba_tasks()
    code, symbol = compiled
    _store(name, code, {**cpu, "symbol": symbol, "sha256": hashlib.sha256(code).hexdigest()})
    return _link(llvm, machine, code, symbol)


def _read(code_path: Path, record_path: Path, cpu: dict) -> tuple[bytes, str] | None:
    """The object code and symbol of a cache entry that is whole and made for this CPU."""
    try:
        record = json.loads(record_path.read_text())
        code = code_path.read_bytes()
    except (OSError, ValueError):
        return None
    if not isinstance(record, dict) or any(record.get(k) != v for k, v in cpu.items()):
        return None
    if record.get("sha256") != hashlib.sha256(code).hexdigest() or "symbol" not in record:
        return None  # cut short or changed: compile afresh rather than load it
    return code, str(record["symbol"])


def _compile(llvm: Any, machine: Any, key: tuple[str, str, str]) -> tuple[bytes, str] | None:
    """numba's IR of the kernel with its runtime helpers made traps, as object code and its
    symbol; None if the IR still needs something from outside (loading it could abort)."""
    from diffdrive.backends.numba_simulate import kernel_ir

    ir, symbol = kernel_ir(*key)
    module = llvm.parse_assembly(trap_runtime_helpers(ir))
    module.verify()
    unresolved = [
        f.name for f in module.functions if f.is_declaration and not f.name.startswith("llvm.")
    ]
    unresolved += [g.name for g in module.global_variables if g.is_declaration]
    if unresolved:  # a form of declaration the rewrite does not know
        return None
    return machine.emit_object(module), symbol


def trap_runtime_helpers(ir: str) -> str:
    """``ir`` with every function it declares (but LLVM's intrinsics) defined as a trap, and
    every global it declares defined as zero: the code needs nothing outside itself but libm."""

    def trap(match: re.Match) -> str:
        if match["name"].startswith("llvm."):
            return match[0]
        return (
            f"define internal {match['head']}@{match['name']}({match['arguments']})"
            f"{match['tail']} {{\n  call void @llvm.trap()\n  unreachable\n}}"
        )

    ir = _DECLARATION.sub(trap, ir)
    ir = _EXTERNAL_GLOBAL.sub(r"\g<name> = internal \g<kind> \g<type> zeroinitializer", ir)
    return ir + "\ndeclare void @llvm.trap()\n"


def _link(llvm: Any, machine: Any, code: bytes, symbol: str) -> Callable[..., None]:
    """Load object code into an MCJIT engine; the kernel over NumPy arrays."""
    engine = llvm.create_mcjit_compiler(llvm.parse_assembly(""), machine)
    engine.add_object_file(llvm.ObjectFileRef.from_data(code))
    engine.finalize_object()
    _engines.append(engine)
    function = ctypes.CFUNCTYPE(None, *_C_SIGNATURE)(engine.get_function_address(symbol))

    def kernel(stage: int, inputs: tuple, first: int, stop: int) -> None:
        history, times, angles, start, geometry, midpoint, chord, chunks, turns, out, ends = inputs
        # ctypes releases the GIL for the call.
        function(
            stage,
            history.ctypes.data,
            history.shape[0],
            history.shape[1],
            times.ctypes.data,
            times.shape[0],
            times.shape[1],
            int(angles),
            start.ctypes.data,
            geometry.ctypes.data,
            int(midpoint),
            int(chord),
            chunks,
            turns.ctypes.data,
            out.ctypes.data,
            out.shape[0],
            out.shape[1],
            ends.ctypes.data,
            first,
            stop,
        )

    return kernel


def _store(name: str, code: bytes, record: dict) -> None:
    """Write a cache entry to the first folder that takes it (none: the code is not kept, and
    the next process compiles again)."""
    from diffdrive.atomic import atomic_output, atomic_write

    for folder in _folders():
        try:
            folder.mkdir(parents=True, exist_ok=True)
            with atomic_output(folder / f"{name}.o") as temporary:
                temporary.write_bytes(code)
            with atomic_write(folder / f"{name}.json") as stream:
                stream.write(json.dumps(record))
        except (OSError, ValueError):  # not writable here: try the next folder
            continue
        return


def _folders() -> list[Path]:
    """Where cache entries are looked for and written, in that order."""
    if os.environ.get("DIFFDRIVE_CACHE_DIR"):
        return [Path(os.environ["DIFFDRIVE_CACHE_DIR"])]
    beside = Path(__file__).parent / "__pycache__"
    home = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "diffdrive"
    return [beside, home]


@functools.cache
def _digest() -> str:
    """What a cache entry must have been made from: the kernel's sources (this module's
    too) and numba's and llvmlite's versions."""
    digest = hashlib.sha256()
    here = Path(__file__).parent
    for name in _SOURCES:
        digest.update((here / name).read_bytes())
    for package in ("numba", "llvmlite"):
        digest.update(importlib.metadata.version(package).encode())
    return digest.hexdigest()[:16]
