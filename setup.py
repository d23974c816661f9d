"""The C core of ``diffdrive.Odometry`` (one update in well under a microsecond).

Everything else about the package is in pyproject.toml; setuptools' own table for extension
modules there is still experimental, so the one extension is declared here.
"""

from setuptools import Extension, setup

setup(ext_modules=[Extension("diffdrive._odometry", ["src/diffdrive/_odometry.c"])])
