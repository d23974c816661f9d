/* What the binding's sources share (diffdrive.backends._odometry, over the C core in c/):
 * _odometry.c (Odometry's readings) lends _estimator.c (PoseEstimator's filter) its readings
 * and checks; _module.c's init adds both types. */
#ifndef DIFFDRIVE_BINDING_H
#define DIFFDRIVE_BINDING_H

#include <Python.h>
#include <math.h>

/* -- what _estimator.c takes from _odometry.c -------------------------------------------- */

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

/* -- the cores' settings: one Python object each, read by name ------------------------------ */

/* A sequence of exactly n numbers into out, or -1 with a ValueError naming what. */
static inline int sequence_into(PyObject *obj, double *out, Py_ssize_t n, const char *what) {
    PyObject *seq = PySequence_Fast(obj, what);
    if (seq == NULL) return -1;
    if (PySequence_Fast_GET_SIZE(seq) != n) {
        Py_DECREF(seq);
        PyErr_Format(PyExc_ValueError, "%s must have %zd numbers", what, n);
        return -1;
    }
    for (Py_ssize_t i = 0; i < n; ++i) out[i] = PyFloat_AsDouble(PySequence_Fast_GET_ITEM(seq, i));
    Py_DECREF(seq);
    return PyErr_Occurred() ? -1 : 0;
}

/* The settings' attribute name: a sequence of exactly n numbers into out, or -1. */
static inline int attribute_into(PyObject *settings, const char *name, double *out, Py_ssize_t n) {
    PyObject *value = PyObject_GetAttrString(settings, name);
    if (value == NULL) return -1;
    int status = sequence_into(value, out, n, name);
    Py_DECREF(value);
    return status;
}

/* The settings' attribute name as a float, or -1 with an error. */
static inline int attribute_double(PyObject *settings, const char *name, double *out) {
    PyObject *value = PyObject_GetAttrString(settings, name);
    if (value == NULL) return -1;
    *out = PyFloat_AsDouble(value);
    Py_DECREF(value);
    return *out == -1.0 && PyErr_Occurred() ? -1 : 0;
}

/* The settings' attribute name as an int (a bool's truth, or an index), or -1 with an error. */
static inline int attribute_int(PyObject *settings, const char *name, int *out) {
    PyObject *value = PyObject_GetAttrString(settings, name);
    if (value == NULL) return -1;
    long number = PyBool_Check(value) ? (long)(value == Py_True) : PyLong_AsLong(value);
    Py_DECREF(value);
    if (number == -1 && PyErr_Occurred()) return -1;
    *out = (int)number;
    return 0;
}

#endif
