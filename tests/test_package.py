"""The package as a whole: what importing it loads and what it exports."""

import subprocess
import sys

import pytest

import diffdrive as dd


def python_lines(code: str) -> list[str]:
    """What a fresh Python process prints running ``code``, line by line."""
    return subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout.split("\n")


def test_import_loads_numpy_and_nothing_heavier():
    code = (
        "import sys, diffdrive\n"
        "heavy = {'scipy', 'matplotlib', 'numba', 'pandas', 'torch', 'jax'}\n"
        "print(sorted(heavy & {m.split('.')[0] for m in sys.modules}))\n"
        "print('numpy' in sys.modules)\n"
    )
    out = python_lines(code)
    assert out[0] == "[]"
    assert out[1] == "True"


def test_public_names_exist():
    for name in dd.__all__:
        assert hasattr(dd, name), name
    for name in dd.batch.__all__:
        assert callable(getattr(dd.batch, name)), name
    for name in dd.se2.__all__:
        assert callable(getattr(dd.se2, name)), name


def test_scalar_and_batch_se2_offer_the_same_operations():
    assert set(dd.se2.__all__) - set(dd.batch.__all__) == set()


def test_the_heavier_modules_are_attributes_loaded_on_first_use():
    code = (
        "import sys, diffdrive as dd\n"
        "before = 'diffdrive.calibration' in sys.modules\n"
        "names = ['calibration', 'evaluation', 'io', 'plot', 'montecarlo']\n"
        "print(before, all(getattr(dd, n).__name__ == 'diffdrive.' + n for n in names))\n"
        "print('calibration' in dir(dd))\n"
    )
    out = python_lines(code)
    assert out[:2] == ["False True", "True"]


def test_import_loads_the_core_and_the_rest_on_first_use():
    """``import diffdrive`` loads the core (types, model, se2, integrate, simulate, odometry);
    the estimators, control, dynamics and the rest come with the first name that needs them,
    each the object its module defines."""
    code = (
        "import sys, diffdrive as dd\n"
        "late = ['control', 'dynamics', 'estimation.fusion', 'estimation.smoother', 'io']\n"
        "print([m for m in late if 'diffdrive.' + m in sys.modules])\n"
        "from diffdrive.control.limiter import Limiter\n"
        "from diffdrive.estimation.smoother import estimate_trajectory\n"
        "from diffdrive import estimation\n"
        "print(dd.Limiter is Limiter, estimation.estimate_trajectory is estimate_trajectory)\n"
    )
    out = python_lines(code)
    assert out[:2] == ["[]", "True True"]


def test_no_face_names_a_function_as_one_of_its_modules():
    """A name a face exports is never also one of its submodules (``control.follow`` was the
    function and a module: the reference documented the module, and importing the module
    could hide the function); a submodule imported first leaves the face's names as they
    are."""
    import importlib
    import pkgutil

    import diffdrive

    packages = ["diffdrive"] + [
        found.name
        for found in pkgutil.walk_packages(diffdrive.__path__, "diffdrive.")
        if found.ispkg
    ]
    for name in packages:
        package = importlib.import_module(name)
        submodules = {found.name for found in pkgutil.iter_modules(package.__path__)}
        for exported in getattr(package, "__all__", ()):
            if exported in submodules:
                value = getattr(package, exported)
                assert getattr(value, "__name__", None) == f"{name}.{exported}", (name, exported)
    code = (
        "import diffdrive.control.closed_loop as module\n"
        "from diffdrive import control\n"
        "print(control.follow is module.follow)\n"
        "print(sorted(set(control.__all__) - set(dir(control))))\n"
    )
    assert python_lines(code)[:2] == ["True", "[]"]


def test_every_lazy_name_is_its_modules():
    from diffdrive import control, estimation

    for package in (control, estimation):
        assert sorted(package.__all__) == sorted(package._NAMES)
        for name in package.__all__:
            assert getattr(package, name) is not None, name


def test_unknown_attributes_still_raise():
    import pytest

    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        dd.nope  # noqa: B018


def test_the_version_is_written_once():
    from importlib.metadata import version
    from pathlib import Path

    assert version("diffdrive") == dd.__version__
    pyproject = (Path(__file__).parents[1] / "pyproject.toml").read_text()
    assert dd.__version__ not in pyproject
    assert 'requires = ["setuptools>=77"]' in pyproject  # license = "MIT" needs 77


def test_auto_loads_numba_only_for_calls_where_it_pays_off():
    code = (
        "import sys, numpy as np, diffdrive as dd\n"
        "robot = dd.DiffDrive(wheel_radius=0.05, track_width=0.3)\n"
        "dd.simulate(robot, np.ones((2**17, 2)), dt=0.01)\n"
        "print('numba' in sys.modules)\n"
        "from diffdrive.simulation import _use_numba\n"
        "dd.simulate(robot, np.ones((2, 2)), dt=0.01, backend='numba')\n"
        "print(_use_numba('auto', 2**17, np.dtype('float64')))\n"
    )
    out = python_lines(code)
    assert out[:2] == ["False", "True"]


@pytest.mark.slow
def test_the_wheel_carries_the_type_information_and_the_page(tmp_path):
    """A built wheel, not the editable tree: py.typed, the C extension's stub, the marimo page."""
    import zipfile
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "wheel",
            str(root),
            "--no-deps",
            "--no-build-isolation",
            "-q",
            "-w",
            str(tmp_path),
        ],
        check=True,
        capture_output=True,
    )
    (wheel,) = tmp_path.glob("diffdrive-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    wanted = ("diffdrive/py.typed", "diffdrive/backends/_odometry.pyi", "diffdrive/learn/page.py")
    for needed in wanted:
        assert needed in names, needed
