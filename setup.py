"""The C core of ``diffdrive.Odometry`` (one update in well under a microsecond).

Everything else about the package is in pyproject.toml; setuptools' own table for extension
modules there is still experimental, so the one extension is declared here. It is optional:
where no C compiler is found the build goes on without it, and ``diffdrive.Odometry`` runs on
its pure-Python twin (``backends/odometry_python.py``; ``diffdrive.odometry.COMPILED`` says which).
"""

from setuptools import Extension, setup

CORE = Extension(
    "diffdrive.backends._odometry", ["src/diffdrive/backends/_odometry.c"], optional=True
)
setup(ext_modules=[CORE])
