/* What the sources of diffdrive.backends._odometry share: _odometry.c (Odometry's wheel
 * readings and step) lends _estimator.c (PoseEstimator's filter) its readings, checks and
 * sinc; _module.c's init adds both types. */
#ifndef DIFFDRIVE_BINDING_H
#define DIFFDRIVE_BINDING_H

#include <Python.h>
#include <math.h>

/* -- the step's maths, once for both sources (diffdrive._step, which they mirror) -------- */

/* sin(u)/u by the rule of diffdrive._step.sinc: its Taylor form to u^8 below 1/16, libm
 * above, with the same operations in the same order. */
static inline double dd_sinc(double u) {
    if (fabs(u) >= 1.0 / 16.0) return sin(u) / u;
    double u2 = u * u;
    return 1.0 - u2 * (1.0 / 6) *
                     (1.0 - u2 * (1.0 / 20) * (1.0 - u2 * (1.0 / 42) * (1.0 - u2 * (1.0 / 72))));
}

/* d/du of sin(u)/u: (u cos u - sin u)/u^2, with its Taylor form near 0 where that cancels. */
static inline double dd_sinc_derivative(double u) {
    if (fabs(u) < 0.05) {
        double u2 = u * u;
        return -u / 3.0 * (1.0 - u2 / 10.0 * (1.0 - u2 / 28.0 * (1.0 - u2 / 54.0)));
    }
    return (u * cos(u) - sin(u)) / (u * u);
}

/* _step.move_jacobians: the world move (dx, dy) of a step that goes forward and turns (the
 * reference point offset m to the left of the axle's line sideways by offset * turn) from
 * heading, its direction at heading + weight * turn and its length times sinc(turn / 2) if
 * chord; and its derivatives bf in forward and bt in turn. */
static inline void dd_move_jacobians(double forward, double offset, double turn, double weight,
                                     int chord, double heading, double *dx, double *dy,
                                     double bf[2], double bt[2]) {
    double angle = heading + weight * turn, ca = cos(angle), sa = sin(angle);
    double sideways = offset * turn;
    double gx = ca * forward - sa * sideways, gy = sa * forward + ca * sideways;
    double scale = 1.0, slope = 0.0;
    if (chord) {
        scale = dd_sinc(0.5 * turn);
        slope = 0.5 * dd_sinc_derivative(0.5 * turn);
    }
    bt[0] = slope * gx + scale * (-sa * offset - gy * weight);
    bt[1] = slope * gy + scale * (ca * offset + gx * weight);
    *dx = scale * gx;
    *dy = scale * gy;
    bf[0] = scale * ca;
    bf[1] = scale * sa;
}

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
