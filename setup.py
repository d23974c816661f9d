"""The C cores of ``diffdrive.Odometry`` (one update in well under a microsecond) and of
``diffdrive.estimation.PoseEstimator``: one extension, the Python binding of the C core in
``c/``.

Everything else about the package is in pyproject.toml; setuptools' own table for extension
modules there is still experimental, so the one extension is declared here. It is optional:
where no C compiler is found the build goes on without it, and ``diffdrive.Odometry`` runs on
its pure-Python twins (``estimation/_odometry_python.py``, ``estimation/_estimator_python.py``;
``COMPILED`` in ``diffdrive.estimation._cores`` says which).
"""

import sys
from glob import glob

from setuptools import Extension, setup

# The binding (src/diffdrive/backends/) over the freestanding C core (c/): the same sources the
# firmware builds, compiled here in double precision.
CORE = Extension(
    "diffdrive.backends._odometry",
    [
        "src/diffdrive/backends/_module.c",
        "src/diffdrive/backends/_odometry.c",
        "src/diffdrive/backends/_estimator.c",
        "src/diffdrive/backends/_partition.c",
        *sorted(glob("c/src/*.c")),
    ],
    include_dirs=["c/include", "c/src"],
    # No fused multiply-adds the source does not write: the extension's numbers are then the
    # same on every processor, and the same as c/'s own builds (-std=c99 leaves them out).
    extra_compile_args=[] if sys.platform == "win32" else ["-ffp-contract=off"],
    depends=[
        "src/diffdrive/backends/_odometry.h",
        *glob("c/include/diffdrive/*.h"),
        *glob("c/src/*.h"),
    ],
    optional=True,
)
setup(ext_modules=[CORE])
