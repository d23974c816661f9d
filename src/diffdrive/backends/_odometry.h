/* What the sources of diffdrive.backends._odometry share: _odometry.c (Odometry's wheel
 * readings and step) lends _estimator.c (PoseEstimator's filter) its readings, checks and
 * sinc; _module.c's init adds both types. */
#ifndef DIFFDRIVE_ODOMETRY_H
#define DIFFDRIVE_ODOMETRY_H

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

#endif
