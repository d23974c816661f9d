/* What the sources of diffdrive.backends._odometry share: _odometry.c (Odometry's wheel
 * readings and step) lends _estimator.c (PoseEstimator's filter) its readings, checks and
 * sinc; _module.c's init adds both types. */
#ifndef DIFFDRIVE_ODOMETRY_H
#define DIFFDRIVE_ODOMETRY_H

#include <Python.h>

double dd_sinc(double u);
double dd_sinc_derivative(double u);

/* An OdometryCore (or subclass) object. */
int odometry_check(PyObject *obj);
/* update_ticks (kind 0), _positions (1), _increments (2) or _velocities (3) with args
 * (left, right, t or dt): None, or NULL with the exception set and the core unchanged. */
PyObject *odometry_update(PyObject *core, int kind, PyObject *const *args, Py_ssize_t nargs);
double odometry_time(PyObject *core);
void odometry_arcs(PyObject *core, double arcs[2]);
PyObject *odometry_snapshot(PyObject *core);
int odometry_restore(PyObject *core, PyObject *saved);

/* _partition.c: the episodes' optimal partitioning. */
PyObject *dd_partition(PyObject *module, PyObject *const *args, Py_ssize_t nargs);

int odometry_add_type(PyObject *module);
int estimator_add_type(PyObject *module);

#endif
