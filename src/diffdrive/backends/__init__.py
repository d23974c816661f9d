"""The backends that run the step of ``diffdrive._step``, together.

- NumPy blocked prefix sums: ``diffdrive.simulation`` (``simulate``'s default path);
- any array-API library (JAX, PyTorch, CuPy, ...), functional and differentiable:
  ``diffdrive.batch.integration``;
- numba: ``numba_simulate`` (``simulate``'s compiled kernel, and ``_step``'s functions
  compiled), ``simulate_kernel`` (that kernel's machine code cached on disk and loaded without
  numba, and the threads that run it) and ``numba_montecarlo`` (the reduce-only Monte Carlo);
- C: ``_odometry`` (``_odometry.c``, ``_estimator.c``, ``_partition.c``), the Python binding
  of the C core in ``c/`` (the same sources a robot's firmware builds), the cores of
  ``diffdrive.Odometry`` and ``PoseEstimator``, built from ``settings``' values; their
  pure-Python twins, for installations without a C compiler and as the reference the tests
  hold the C to, sit beside the classes they back in ``diffdrive.estimation``
  (``_odometry_python``, ``_estimator_python``), as they are written on its filter's maths;
  ``diffdrive.estimation._cores`` chooses.

``tests/test_backends.py`` holds every one of them to one table of cases. The numba modules
import numba, so nothing imports them until a caller asks for that backend (and ``simulate``'s
kernel, once cached, not even then).
"""
