"""The package as a whole: what importing it loads and what it exports."""

import subprocess
import sys

import diffdrive as dd


def test_import_loads_numpy_and_nothing_heavier():
    code = (
        "import sys, diffdrive\n"
        "heavy = {'scipy', 'matplotlib', 'numba', 'pandas', 'torch', 'jax'}\n"
        "print(sorted(heavy & {m.split('.')[0] for m in sys.modules}))\n"
        "print('numpy' in sys.modules)\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout.split("\n")
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
