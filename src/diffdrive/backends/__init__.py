"""The backends that run the step of ``diffdrive._step``, together.

- NumPy blocked prefix sums: ``diffdrive.simulation`` (``simulate``'s default path);
- any array-API library (JAX, PyTorch, CuPy, ...), functional and differentiable:
  ``diffdrive.batch.rollout``;
- numba: ``numba_simulate`` (``simulate``'s compiled kernel, and ``_step``'s functions
  compiled), ``simulate_kernel`` (that kernel's machine code cached on disk and loaded without
  numba, and the threads that run it) and ``numba_montecarlo`` (the reduce-only Monte Carlo);
- C: ``_odometry`` (``_odometry.c``), the core of ``diffdrive.Odometry``, and its pure-Python
  twin ``odometry_python`` for installations without a C compiler.

``tests/test_backends.py`` holds every one of them to one table of cases. The numba modules
import numba, so nothing imports them until a caller asks for that backend (and ``simulate``'s
kernel, once cached, not even then).
"""
